"""``loosefit simulate``: a garment data set simulated with Newton's VBD cloth solver."""

from __future__ import annotations

import argparse

from loosefit.cli.common import add_import_args, log, offset, parse_shape


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a garment dataset with Newton (resumable)")
    p.add_argument(
        "--preset",
        default="demo",
        help="tiny, demo, salsa, salsa-speed, salsa-speeds, dance, dance-speed, dance-pitch, "
        "dance-spin, dance-spins, dance-spins-slow, dance-turns, paper, dress-tiny or dress",
    )
    p.add_argument(
        "--config",
        default=None,
        metavar="FILE",
        help="a data set configuration (.yaml, .yml or .toml) instead of a preset; "
        "--write-config writes one to start from",
    )
    p.add_argument(
        "--write-config",
        default=None,
        metavar="FILE",
        help="write the configuration (a preset's, with the options below) and stop",
    )
    p.add_argument(
        "--garment",
        default=None,
        help="aline, flared, circle, dress, dress-strapless, or a garment file "
        "(.obj, .gltf, .glb; see loosefit garment) instead of the preset's",
    )
    p.add_argument(
        "--resolution",
        default="cpu",
        choices=("cpu", "paper"),
        help="with a parametric --garment",
    )
    p.add_argument(
        "--motions",
        default=None,
        metavar="FOLDER_OR_SPECS",
        help="a folder of BVH files, or comma-separated motions (files, moves, "
        "dance:SECONDS, mirror:..., speed:F:..., pitch:D:..., spin:T:..., A+B), one clip each",
    )
    p.add_argument(
        "--test",
        nargs="+",
        default=None,
        metavar="NAME",
        help="the clips held out (their names: file stems, or the specs' names)",
    )
    add_import_args(p)
    p.add_argument(
        "--shape",
        default="",
        help="the avatar's body as anny phenotypes in [0, 1], e.g. "
        "'weight=0.7,height=0.6' (a garment --fit to one: its shape)",
    )
    p.add_argument("--out", default=None, help="dataset folder (default datasets/PRESET)")
    p.add_argument(
        "--bvh",
        default=None,
        help="salsa, dance, paper: the salsa folder of BVH clips "
        "(dance: with cmu-ballet beside it)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=2,
        help="parallel simulations (--ray: the CPUs of a Ray instance it starts "
        "here when none runs)",
    )
    p.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="simulate every clip as a task on a Ray cluster: the head's HOST:PORT "
        "(`ray start --head` prints it), or none: RAY_ADDRESS, the cluster of this "
        "machine, else a new one here; --out on storage every node shares "
        "(docs/use/CLUSTER.md; pip install 'loosefit[cluster]')",
    )
    p.add_argument(
        "--save-every",
        type=int,
        default=50,
        metavar="FRAMES",
        help="frames between the saves of a clip's state, from which a killed run goes on",
    )
    p.add_argument(
        "--batch",
        type=int,
        default=1,
        metavar="K",
        help="clips simulated at once as worlds of one model (a GPU: 16-64)",
    )
    p.add_argument(
        "--prepare-workers",
        type=int,
        default=None,
        metavar="N",
        help="with --batch: processes that load and pose-correct every clip's motion "
        "before the first batch (default: every CPU core)",
    )
    p.add_argument("--device", default=None, help="warp device: cpu or cuda:0")
    p.add_argument("--max-frames", type=int, default=None, help="frames kept per clip")
    _add_clip_args(p)
    p.set_defaults(func=run)


def _add_clip_args(p) -> None:
    """What each clip is: its members (an ensemble), its poses, a clip taken from elsewhere."""
    p.add_argument(
        "--seeds",
        default=None,
        metavar="S,S,...",
        help="an ensemble: each clip simulated once per seed (e.g. 0,1,2,3), each run a "
        "member with the clip's motion and its cloth's start jittered from its own seed; "
        "the member of the data set's seed keeps the clip's name, the others are NAME@seedS",
    )
    p.add_argument(
        "--keep-poses",
        action="store_true",
        help="simulate the motion exactly as captured: do not turn a limb that "
        "passes into the body out of it (unfold.enabled: false)",
    )
    p.add_argument(
        "--reuse",
        default=None,
        metavar="FOLDER",
        help="take the clips this dataset shares with the one in FOLDER (simulated "
        "alike) instead of simulating them again",
    )


def dataset_config(args: argparse.Namespace):
    """The data set ``simulate`` makes (:func:`loosefit.api.simulation.dataset_config`):
    ``--config FILE`` or ``--preset``, then ``--garment``, ``--motions``, ``--test``,
    ``--seeds``, ``--device``, ``--shape``, ``--max-frames``, ``--keep-poses`` over it."""
    from loosefit.api.simulation import dataset_config as config_of
    from loosefit.api.simulation import parametric_garments

    seeds = getattr(args, "seeds", None)
    shape = getattr(args, "shape", "")
    is_file = args.garment and args.garment not in parametric_garments()
    return config_of(
        preset=args.preset,
        config_file=args.config,
        bvh=args.bvh,
        garment=args.garment,
        resolution=args.resolution,
        units=args.units,
        up=args.up,
        kind=args.kind,
        offset=offset(args.offset) if is_file else (0.0, 0.0, 0.0),
        attach=args.attach,
        motions=args.motions,
        test=args.test,
        seeds=parse_seeds(seeds) if seeds is not None else None,
        device=args.device,
        shape=parse_shape(shape) if shape else None,  # the manifest carries it on to training
        max_frames=args.max_frames,
        keep_poses=getattr(args, "keep_poses", False),
    )


def parse_seeds(text: str) -> list[int]:
    """``--seeds 0,1,2`` as ``[0, 1, 2]``: distinct integers >= 0, at least one
    (:func:`loosefit.api.simulation.parse_seeds`)."""
    from loosefit.api.simulation import parse_seeds as parse

    return parse(text, source="--seeds")


def run(args: argparse.Namespace) -> int:
    from loosefit.api.simulation import simulate_dataset, simulation_report, write_dataset_config

    config = dataset_config(args)
    if args.write_config:
        write_dataset_config(config, args.write_config)
        log(
            f"wrote {args.write_config}: `loosefit simulate --config {args.write_config}` "
            "makes this data set"
        )
        return 0
    if args.out is None:
        args.out = f"datasets/{config.preset}"
    manifest = simulate_dataset(
        config,
        args.out,
        workers=args.workers,
        progress=True,
        reuse=args.reuse,
        batch=args.batch,
        save_every=args.save_every,
        cluster=False if args.ray is None else (args.ray or True),  # --ray [ADDRESS]
        prepare_workers=args.prepare_workers,
    )
    print(simulation_report(manifest))
    log(f"dataset in {args.out}")
    return 0
