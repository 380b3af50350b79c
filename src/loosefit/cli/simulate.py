"""``loosefit simulate``: a garment data set simulated with Newton's VBD cloth solver."""

from __future__ import annotations

import argparse
from pathlib import Path

from loosefit.cli.common import add_import_args, log, offset, parse_shape


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a garment dataset with Newton (resumable)")
    p.add_argument(
        "--preset",
        default="demo",
        help="tiny, demo, salsa, salsa-speed, salsa-speeds, dance, paper, dress-tiny or dress",
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
        "dance:SECONDS, mirror:..., speed:F:..., A+B), one clip each",
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
    """The data set ``simulate`` makes: ``--config FILE`` or ``--preset``, then
    ``--garment``, ``--motions``, ``--test``, ``--seeds``, ``--device``, ``--shape``,
    ``--max-frames``, ``--keep-poses`` over it."""
    from loosefit.sim.dataset_config import MotionSource, read_config_file
    from loosefit.sim.presets import preset

    config = read_config_file(args.config) if args.config else preset(args.preset, args.bvh)
    if args.garment:
        _set_garment(config, args)
    if args.motions:
        folder = Path(args.motions)
        test = tuple(args.test or ())
        if folder.is_dir():
            config.motions = MotionSource(kind="bvh", folder=str(folder.resolve()), test=test)
        else:
            specs = tuple(t for t in args.motions.split(",") if t)
            config.motions = MotionSource(kind="specs", specs=specs, test=test)
        config.preset = "custom"
    elif args.test:
        config.motions.test = tuple(args.test)
    if getattr(args, "seeds", None) is not None:
        config.seeds = parse_seeds(args.seeds)
    if args.device:
        config.cloth.device = args.device
    if getattr(args, "shape", ""):  # the avatar's body: the manifest carries it on to training
        config.shape = parse_shape(args.shape)
        config.preset = "custom"
    if args.max_frames is not None:
        config.motions.max_frames = args.max_frames
    if getattr(args, "keep_poses", False):
        config.unfold.enabled = False
    return config


def parse_seeds(text: str) -> list[int]:
    """``--seeds 0,1,2`` as ``[0, 1, 2]``, checked as ``DatasetConfig.seeds`` is
    (``check_seeds``): distinct integers >= 0, at least one."""
    from loosefit.errors import LoosefitInputError
    from loosefit.sim.dataset_config import check_seeds

    seeds = []
    for item in filter(None, (s.strip() for s in text.split(","))):
        try:
            seeds.append(int(item))
        except ValueError:
            raise LoosefitInputError(
                "--seeds",
                "seeds",
                "comma-separated integers >= 0, e.g. 0,1,2",
                f"{item!r} in {text!r}",
            ) from None
    return check_seeds(seeds, "--seeds")


def _set_garment(config, args: argparse.Namespace) -> None:
    """``--garment``: a skirt style, a dress, or a garment file, in place of the preset's."""
    from loosefit.garment.dress import DRESS_SPECS, DressConfig
    from loosefit.garment.skirt import STYLES, SkirtConfig
    from loosefit.sim.dataset_config import GarmentFile

    g = args.garment
    if g in STYLES:
        config.garment = SkirtConfig.preset(args.resolution, g)
    elif g in DRESS_SPECS:
        config.garment = DressConfig.preset(args.resolution, DRESS_SPECS[g])
    else:
        config.garment = GarmentFile(
            str(Path(g).resolve()), args.units, args.up, args.kind, offset(args.offset), args.attach
        )
    config.preset = "custom"
    kind = "dress" if g in DRESS_SPECS else "skirt" if g in STYLES else args.kind
    if kind is None:  # a file: a dress if it has straps (as the import will guess)
        from loosefit.garment.importer import detect_kind, read_garment_mesh

        kind = detect_kind(read_garment_mesh(g).faces)
    if kind == "dress" and config.cloth.arm_collision is False:
        config.cloth.arm_collision = "upper"  # a dress's bodice reaches the upper arms


def run(args: argparse.Namespace) -> int:
    from loosefit.sim.dataset_config import write_config_file
    from loosefit.sim.generate import generate
    from loosefit.sim.report import format_report

    config = dataset_config(args)
    if args.write_config:
        write_config_file(config, args.write_config)
        log(
            f"wrote {args.write_config}: `loosefit simulate --config {args.write_config}` "
            "makes this data set"
        )
        return 0
    if args.out is None:
        args.out = f"datasets/{config.preset}"
    cluster = None
    if args.ray is not None:  # --ray [ADDRESS]: every clip a task on a Ray cluster
        from loosefit.sim.cluster import ClusterConfig

        cluster = ClusterConfig(address=args.ray or None)
    manifest = generate(
        config,
        args.out,
        workers=args.workers,
        progress=True,
        reuse=args.reuse,
        batch=args.batch,
        resume_every=args.save_every,
        cluster=cluster,
        prepare_workers=args.prepare_workers,
    )
    print(format_report(manifest))
    log(f"dataset in {args.out}")
    return 0
