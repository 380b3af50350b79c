"""Ground truth through the API: a data set's configuration from a preset or a file and the
choices over it, the data set simulated (in processes here or on a Ray cluster) and its
report; a garment simulated on a given avatar. Each imports what it needs when called.

::

    from loosefit.api.simulation import dataset_config, simulate_dataset, simulation_report

    config = dataset_config(preset="tiny", garment="dress", max_frames=30)
    manifest = simulate_dataset(config, "datasets/mine", workers=4)
    print(simulation_report(manifest))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

Progress = Callable[[int, int], None]  # progress(done, total)


def parametric_garments() -> tuple[str, ...]:
    """The garments made to measure on the avatar, by name: the skirt styles
    (:data:`~loosefit.garment.skirt.STYLES`) and the dresses
    (:data:`~loosefit.garment.dress.DRESS_SPECS`); any other garment is a file."""
    from loosefit.garment.dress import DRESS_SPECS
    from loosefit.garment.skirt import STYLES

    return STYLES + tuple(DRESS_SPECS)


def parse_seeds(text: str, *, source: str = "seeds") -> list[int]:
    """An ensemble's seeds written ``"0,1,2"`` as ``[0, 1, 2]``, checked as
    ``DatasetConfig.seeds`` is (:func:`~loosefit.sim.dataset_config.check_seeds`):
    distinct integers >= 0, at least one.

    Raises:
        LoosefitInputError: naming ``source``: an item that is not an integer, a seed
            below 0 or given twice, none at all.
    """
    from loosefit.errors import LoosefitInputError
    from loosefit.sim.dataset_config import check_seeds

    seeds = []
    for item in filter(None, (s.strip() for s in text.split(","))):
        try:
            seeds.append(int(item))
        except ValueError:
            raise LoosefitInputError(
                source,
                "seeds",
                "comma-separated integers >= 0, e.g. 0,1,2",
                f"{item!r} in {text!r}",
            ) from None
    return check_seeds(seeds, source)


def dataset_config(
    *,
    preset: str = "demo",
    config_file: str | Path | None = None,
    bvh: str | Path | None = None,
    garment: str | None = None,
    resolution: str = "cpu",
    units: str | None = None,
    up: str | None = None,
    kind: str | None = None,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    attach: str = "auto",
    motions: str | None = None,
    test: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    device: str | None = None,
    shape: dict | None = None,
    max_frames: int | None = None,
    keep_poses: bool = False,
):
    """The configuration of a data set (:class:`~loosefit.sim.dataset_config.DatasetConfig`):
    a preset's, or a file's, with the choices given over it.

    Args:
        preset: a named data set (:func:`~loosefit.sim.presets.preset`: ``tiny``, ``demo``,
            ``salsa``, ``dance``, ``paper``, ``dress``, ...).
        config_file: a ``.yaml``/``.yml``/``.toml`` configuration, in place of ``preset``.
        bvh: the salsa clips' folder the salsa and dance presets read (the ballet clips in
            ``cmu-ballet`` beside it).
        garment: a skirt style or a dress (:func:`parametric_garments`), or a garment file
            (``.obj``, ``.gltf``, ``.glb``), in place of the preset's; a dress, or a file
            with straps, brings the upper arms into the collider.
        resolution: a parametric garment's mesh preset (``cpu``, ``paper``).
        units, up, kind, offset, attach: how a garment file is read and placed
            (:func:`~loosefit.fitting.place.import_garment`; offset in metres).
        motions: a folder of motion files, or comma-separated motions (files, moves,
            ``dance:SECONDS``, ``mirror:...``, ``speed:F:...``, ``pitch:D:...``,
            ``spin:T:...``, ``A+B``), one clip each.
        test: the clips held out, by name.
        seeds: an ensemble's member seeds (distinct integers >= 0), one run of each clip
            each.
        device: the simulator's warp device (``cpu``, ``cuda:0``).
        shape: the avatar's phenotype (anny's names, values in [0, 1]); the manifest
            carries it on to training.
        max_frames: frames kept per clip.
        keep_poses: simulate the motions exactly as captured (no limb turned out of the
            body).

    Returns:
        The ``DatasetConfig``; ``preset`` is ``"custom"`` once a garment, motions or a
        shape replace the preset's.

    Raises:
        LoosefitInputError: an unknown preset, an unreadable configuration file or garment
            file, bad seeds.
    """
    from loosefit.sim.dataset_config import MotionSource, check_seeds, read_config_file
    from loosefit.sim.presets import preset as named

    config = read_config_file(config_file) if config_file else named(preset, bvh)
    if garment:
        _set_garment(config, garment, resolution, (units, up, kind, offset, attach))
    if motions:
        folder, held_out = Path(motions), tuple(test or ())
        if folder.is_dir():
            config.motions = MotionSource(kind="bvh", folder=str(folder.resolve()), test=held_out)
        else:
            specs = tuple(t for t in motions.split(",") if t)
            config.motions = MotionSource(kind="specs", specs=specs, test=held_out)
        config.preset = "custom"
    elif test:
        config.motions.test = tuple(test)
    if seeds is not None:
        config.seeds = check_seeds(list(seeds), "seeds")
    if device:
        config.cloth.device = device
    if shape is not None:  # the avatar's body: the manifest carries it on to training
        config.shape = dict(shape)
        config.preset = "custom"
    if max_frames is not None:
        config.motions.max_frames = max_frames
    if keep_poses:
        config.unfold.enabled = False
    return config


def _set_garment(config, garment: str, resolution: str, file_options: tuple) -> None:
    """A skirt style, a dress, or a garment file (read and placed by ``file_options``:
    units, up, kind, offset, attach) in place of the configuration's garment."""
    from loosefit.garment.dress import DRESS_SPECS, DressConfig
    from loosefit.garment.skirt import STYLES, SkirtConfig
    from loosefit.sim.dataset_config import GarmentFile

    units, up, kind, offset, attach = file_options
    if garment in STYLES:
        config.garment = SkirtConfig.preset(resolution, garment)
    elif garment in DRESS_SPECS:
        config.garment = DressConfig.preset(resolution, DRESS_SPECS[garment])
    else:
        config.garment = GarmentFile(str(Path(garment).resolve()), units, up, kind, offset, attach)
    config.preset = "custom"
    kind = "dress" if garment in DRESS_SPECS else "skirt" if garment in STYLES else kind
    if kind is None:  # a file: a dress if it has straps (as the import will guess)
        from loosefit.garment.importer import detect_kind, read_garment_mesh

        kind = detect_kind(read_garment_mesh(garment).faces)
    if kind == "dress" and config.cloth.arm_collision is False:
        config.cloth.arm_collision = "upper"  # a dress's bodice reaches the upper arms


def write_dataset_config(config, path: str | Path) -> Path:
    """``config`` written as YAML (``.yaml``/``.yml``, atomically), which
    :func:`dataset_config` (``config_file=``) reads back as the same data set.

    Raises:
        LoosefitInputError: another suffix.
    """
    from loosefit.sim.dataset_config import write_config_file

    return write_config_file(config, path)


def simulate_dataset(
    config,
    out: str | Path,
    *,
    workers: int = 1,
    progress: bool = True,
    reuse: str | Path | None = None,
    batch: int = 1,
    save_every: int = 50,
    cluster: bool | str = False,
    prepare_workers: int | None = None,
) -> dict:
    """The data set of ``config`` (:func:`dataset_config`) simulated into the folder ``out``
    (new, empty, or a killed run of the same configuration, which goes on):
    :func:`loosefit.sim.generate.generate`.

    Args:
        config: the ``DatasetConfig``.
        out: the data set folder.
        workers: parallel simulations (a CPU core each); with ``cluster``, the CPUs of the
            Ray instance started here when none runs.
        progress: a bar over the frames, with rate and time to go.
        reuse: another data set folder whose clips of the same simulation are taken
            instead of simulated again.
        batch: clips simulated at once as worlds of one model (a GPU: 16-64).
        save_every: frames between the saves of a clip's state, from which a killed run
            goes on.
        cluster: False: processes of this machine; True: every clip a task on the Ray
            cluster found (``RAY_ADDRESS``, the cluster of this machine, else a new one
            here); a head's address (``HOST:PORT``, ``ray://HOST:PORT``, ``auto``): that
            cluster's. ``out`` on storage every node shares (docs/use/CLUSTER.md).
        prepare_workers: with ``batch`` > 1, the processes that load and pose-correct every
            clip's motion first (default: every CPU core).

    Returns:
        The data set's manifest (:func:`simulation_report` puts it in words).
    """
    from loosefit.sim.generate import generate

    ray = None
    if cluster is not False:  # every clip a task on a Ray cluster
        from loosefit.sim.cluster import ClusterConfig

        ray = ClusterConfig(address=None if cluster is True else cluster)
    return generate(
        config,
        out,
        workers=workers,
        progress=progress,
        reuse=reuse,
        batch=batch,
        resume_every=save_every,
        cluster=ray,
        prepare_workers=prepare_workers,
    )


def simulation_report(manifest: dict) -> str:
    """A simulated data set's manifest in words: its clips, frames, time, devices, the
    clips flagged by the quality limits (:func:`loosefit.sim.report.format_report`)."""
    from loosefit.sim.report import format_report

    return format_report(manifest)


def simulate_garment(
    avatar,
    template,
    motion,
    *,
    device: str = "cpu",
    seed: int = 0,
    progress: Progress | None = None,
):
    """A garment simulated on ``avatar`` through ``motion`` exactly as given (Newton's VBD
    cloth solver, :func:`loosefit.sim.driver.simulate`; the default physics, the upper arms
    in the collider for a dress). :func:`loosefit.simulate` builds the avatar and the
    garment from names instead.

    Args:
        avatar: the :class:`~loosefit.body.avatar.Avatar` the motion drives.
        template: the garment on its rest pose (:class:`~loosefit.types.GarmentTemplate`,
            V vertices).
        motion: T frames on the avatar's skeleton.
        device: the warp device (``cpu``, ``cuda:0``).
        seed: seeds the jitter of the cloth's start.
        progress: called as ``progress(done, total)`` after every simulated frame.

    Returns:
        A :class:`~loosefit.sim.driver.SimResult`: ``garment_vertices`` (T, V, 3) in the
        world frame, ``seconds_per_frame``, ``quality`` (``inside_max``, ``strain_p99``,
        ...).
    """
    from loosefit.fitting.place import collider_arms
    from loosefit.sim.cloth_config import ClothConfig
    from loosefit.sim.driver import simulate

    config = ClothConfig(device=device, seed=seed, arm_collision=collider_arms(template))
    return simulate(avatar, template, motion, config, progress=progress)
