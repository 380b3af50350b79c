"""The paper-scale pipeline on a lent GPU machine, in calls of under 10 minutes.

simulate (the ``paper`` preset: the 9,352-vertex skirt, salsa and procedural dances, clips
batched as worlds of one Newton model) -> train the generative model -> train the motion
encoder -> evaluate on the held-out chain (Table 1's and Table 3's rows) -> package -> time
batched inference. Every step saves what the next needs in ``--work`` and resumes where a
killed one stopped, so ``run`` can be called again and again, each call inside a time budget,
until it says ``done``. What comes back (``--out``) is small: the packaged model (half
precision, a few MiB a file), the tables and the logs, refreshed after every step.

The device machine reaches no package registry and its disk lasts only while it is held
(30 s between calls), and a call carries at most 64 MiB: the packages it lacks (newton,
warp-lang, anny, ...) and the salsa clips travel in parts.

Here, once (makes ``.gpu/part-1`` ... ``part-N``, each fitting one call, and prints the calls)::

    .venv/bin/python scripts/gpu_pipeline.py pack

On the device, one call per part (``carry`` = ``[".gpu/part-K"]``), then the pipeline until
it prints ``done`` (each call under the 10-minute limit)::

    python3 scripts/gpu_pipeline.py receive
    python3 scripts/gpu_pipeline.py run --budget 540 --out $OUT

The ``dance`` set (the ``dance`` data, the salsa set fine-tuned on it as
``scripts/dance_models.sh`` does on the CPU, the detail stage, Table 1's and 3's rows)::

    python3 scripts/gpu_pipeline.py run --preset dance --generative-epochs 10 \
        --motion-epochs 10 --budget 540 --out $OUT

On any machine, the whole plumbing at toy size in a minute (what a test runs)::

    .venv/bin/python scripts/gpu_pipeline.py run --tiny --device cpu --work /tmp/w --out /tmp/o

Exit codes of ``run``: 0 every step done; 3 the budget ran out (call again); 1 a step failed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tarfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEVICE_HOME = Path("/tmp/loosefit-gpu")  # the device machine's working folder
CARRY_BYTES = 62 * 2**20  # what one call may carry, the working tree included (64 MiB)
# What the device's image lacks (it has torch, numpy, scipy, torch_geometric, tqdm, ...).
WHEELS = (
    "warp-lang==1.19.0",
    "newton==1.8.0",
    "anny==0.6.2",
    "roma==1.8.0",
    "trimesh==5.2.0",
    "xatlas==0.0.11",
)
PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64",
             "manylinux2014_x86_64", "manylinux1_x86_64")  # fmt: skip


# -- the steps ----------------------------------------------------------------------------


def dance_steps(work: Path, out: Path, device: str, tiny: bool, mocap: Path, sizes: dict) -> list:
    """The ``dance`` set on a GPU: the ``dance`` data, then the committed salsa set fine-tuned on
    it as ``scripts/dance_models.sh`` does on the CPU (its physics terms and learning rate), the
    detail stage, the package and Table 1's and Table 3's rows on the held-out chain and
    ballet clips. ``tiny``: the same steps on the ``tiny`` preset, a few frames and epochs, each
    stage trained from scratch (the salsa set is of another garment)."""
    cli = [sys.executable, "-m", "loosefit"]
    data, gen, motion, detail = (work / n for n in ("data", "generative", "motion", "detail"))
    base = ROOT / "src" / "loosefit" / "pretrained" / "salsa"
    dev = ["--device", device]
    if tiny:
        simulate = [*cli, "simulate", "--preset", "tiny", "--workers", "1", "--batch", "2"]
        epochs = {"generative": "1", "motion": "1", "detail": "1"}
        precision: list[str] = []
        frames = ["--max-frames", "8"]
        init = {"generative": [], "motion": [], "detail": []}
    else:
        simulate = [*cli, "simulate", "--preset", "dance", "--bvh", str(mocap), "--workers", "1",
                    "--batch", str(sizes["batch"])]  # fmt: skip
        epochs = {s: str(sizes[f"{s}_epochs"]) for s in ("generative", "motion", "detail")}
        precision = ["--precision", sizes["precision"]]
        frames = []
        init = {stage: ["--init", str(base / f"{stage}.pt")] for stage in epochs}
    train = [*cli, "train"]
    common = ["--data", str(data), "--preset", "cpu", "--lr", "3e-4", *dev, *frames]
    package = out / "model"
    evaluate = [*cli, "evaluate", "--checkpoint", str(package / "motion.pt"), "--data", str(data),
                "--split", "test"]  # fmt: skip
    # fmt: off
    return [
        ("simulate", [*simulate, *dev, "--out", str(data)], work / "simulate.done"),
        ("generative", [*train, "generative", *common, "--epochs", epochs["generative"],
                        *precision, *init["generative"], "--membrane", "1000",
                        "--bending", "10", "--collision", "30", "--out", str(gen)],
         gen / "report.json"),
        ("motion", [*train, "motion", *common, "--epochs", epochs["motion"], *precision,
                    "--mirror", "--generative", str(gen / "checkpoint.pt"), *init["motion"],
                    "--membrane", "1000", "--flare", "1", "--out", str(motion)],
         motion / "report.json"),
        ("detail", [*train, "detail", *common, "--epochs", epochs["detail"], "--motion",
                    str(motion / "model.pt"), *init["detail"], "--out", str(detail)],
         detail / "report.json"),
        ("package", [*cli, "package", str(motion / "model.pt"), "--detail",
                     str(detail / "model.pt"), "--out", str(package)], package / "detail.pt"),
        ("table1", [*evaluate, "--no-detail", "--no-collision", "--no-lengths", "--out",
                    str(work / "table1")], work / "table1" / "evaluation.json"),
        ("table3", [*evaluate, "--out", str(work / "table3")],
         work / "table3" / "evaluation.json"),
    ]
    # fmt: on


def steps(work: Path, out: Path, device: str, tiny: bool, mocap: Path, sizes: dict) -> list:
    """(name, command, done-when path) for each step, in order."""
    if sizes.get("preset") == "dance":
        return dance_steps(work, out, device, tiny, mocap, sizes)
    cli = [sys.executable, "-m", "loosefit"]
    data, gen, motion = work / "data", work / "generative", work / "motion"
    if tiny:
        simulate = [*cli, "simulate", "--preset", "tiny", "--workers", "1", "--batch", "2"]
        gen_args = ["--preset", "cpu", "--epochs", "2", "--max-frames", "8"]
        motion_args = ["--preset", "cpu", "--epochs", "2"]
        bench = ["--sizes", "1,4", "--pipeline-sizes", "1,2", "--frames", "4", "--repeats", "1"]
    else:
        simulate = [*cli, "simulate", "--preset", "paper", "--bvh", str(mocap), "--workers", "1",
                    "--batch", str(sizes["batch"])]  # fmt: skip
        if sizes.get("max_frames"):
            simulate += ["--max-frames", str(sizes["max_frames"])]
        gen_args = ["--preset", "full", "--epochs", str(sizes["generative_epochs"]),
                    "--precision", sizes["precision"]]  # fmt: skip
        motion_args = ["--preset", "cpu", "--epochs", str(sizes["motion_epochs"]), "--mirror",
                       "--precision", sizes["precision"]]  # fmt: skip
        bench = ["--sizes", "1,16,256", "--frames", "60"]
    model = motion / "model.pt"
    dev = ["--device", device]
    evaluate = [*cli, "evaluate", "--checkpoint", str(model), "--data", str(data), "--split",
                "test", "--no-detail"]  # fmt: skip
    # fmt: off
    return [
        ("simulate", [*simulate, *dev, "--out", str(data)], work / "simulate.done"),
        ("generative", [*cli, "train", "generative", "--data", str(data), *gen_args, *dev,
                        "--out", str(gen)], gen / "report.json"),
        ("motion", [*cli, "train", "motion", "--data", str(data), "--generative",
                    str(gen / "checkpoint.pt"), *motion_args, *dev, "--out", str(motion)],
         motion / "report.json"),
        # Table 1's row: the motion stage alone; Table 3's: with collision handling (no
        # detail stage is trained here)
        ("table1", [*evaluate, "--no-collision", "--out", str(work / "table1")],
         work / "table1" / "evaluation.json"),
        ("table3", [*evaluate, "--out", str(work / "table3")],
         work / "table3" / "evaluation.json"),
        ("package", [*cli, "package", str(model), "--out", str(out / "model")],
         out / "model" / "motion.pt"),
        ("inference", [sys.executable, str(ROOT / "bench" / "speed" / "batch_inference.py"),
                       *bench, *dev, "--out", str(work / "BATCH_INFERENCE.md")],
         work / "BATCH_INFERENCE.md"),
    ]
    # fmt: on


def environment() -> dict:
    """The steps' environment: this checkout's sources, and the carried packages if any."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    paths = [str(ROOT / "src")]
    if (DEVICE_HOME / "site").is_dir():
        paths.append(str(DEVICE_HOME / "site"))
    env["PYTHONPATH"] = os.pathsep.join(paths + [env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def bring_back(work: Path, out: Path) -> None:
    """Copy the small results into ``out`` (each file well under the 16 MiB limit)."""
    out.mkdir(parents=True, exist_ok=True)
    picks = {
        "manifest.json": work / "data" / "manifest.json",
        "generative_report.md": work / "generative" / "report.md",
        "motion_report.md": work / "motion" / "report.md",
        "detail_report.md": work / "detail" / "report.md",
        "table1.md": work / "table1" / "evaluation.md",
        "table3.md": work / "table3" / "evaluation.md",
        "BATCH_INFERENCE.md": work / "BATCH_INFERENCE.md",
    }
    for name, src in picks.items():
        if src.is_file() and src.stat().st_size < 8 * 2**20:
            shutil.copyfile(src, out / name)
    logs = sorted((work / "logs").glob("*.log"))
    if logs:  # one file: the end of each step's log
        text = "".join(f"== {p.name}\n" + p.read_text(errors="replace")[-20000:] for p in logs)
        (out / "logs.txt").write_text(text)


def run(args: argparse.Namespace) -> int:
    """The next steps, within ``args.budget`` seconds; 0 all done, 3 call again, 1 failed."""
    t_end = time.monotonic() + args.budget
    work, out = Path(args.work), Path(args.out)
    (work / "logs").mkdir(parents=True, exist_ok=True)
    sizes = {"batch": args.batch, "generative_epochs": args.generative_epochs,
             "motion_epochs": args.motion_epochs, "precision": args.precision,
             "max_frames": args.max_frames, "preset": args.preset,
             "detail_epochs": args.detail_epochs}  # fmt: skip
    env = environment()
    for name, cmd, done in steps(work, out, args.device, args.tiny, Path(args.mocap), sizes):
        if done.exists():
            continue
        left = t_end - time.monotonic()
        if left < 20:
            print(f"budget spent before {name}: call again", flush=True)
            bring_back(work, out)
            return 3
        print(f"[{time.strftime('%H:%M:%S')}] {name} ({left:.0f} s left): {' '.join(cmd)}",
              flush=True)  # fmt: skip
        t0 = time.monotonic()
        with open(work / "logs" / f"{name}.log", "a") as log:
            log.write(f"\n# {time.ctime()}: {' '.join(cmd)}\n")
            log.flush()
            try:
                rc = subprocess.run(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
                                    timeout=left - 10).returncode  # fmt: skip
            except subprocess.TimeoutExpired:  # killed: the step resumes on the next call
                print(f"{name}: stopped after {time.monotonic() - t0:.0f} s (budget); call "
                      "again to resume it", flush=True)  # fmt: skip
                bring_back(work, out)
                return 3
        if rc != 0:
            print(f"{name} failed (exit {rc}); its log: {work / 'logs' / (name + '.log')}")
            print((work / "logs" / f"{name}.log").read_text(errors="replace")[-3000:])
            bring_back(work, out)
            return 1
        if name == "simulate":
            done.write_text(json.dumps(json.loads((work / "data" / "manifest.json").read_text())
                                       .get("summary", {})))  # fmt: skip
        print(f"{name}: done in {time.monotonic() - t0:.0f} s", flush=True)
        bring_back(work, out)
    bring_back(work, out)
    print("done", flush=True)
    return 0


# -- the simulator's speed on the GPU (one call) ---------------------------------------------


def sim_speed(args: argparse.Namespace) -> int:
    """The simulator on the GPU in one call: the ``dance`` corpus end to end from a cold
    start (``loosefit simulate``, timed from the command's start; ``--corpus-budget``
    seconds at most), then ``bench/speed/sim_gpu.py``'s table of frames per second by batch,
    with and without graph capture, in what is left of ``--budget``. Results in ``--out``."""
    t_end = time.monotonic() + args.budget
    out, work = Path(args.out), Path(args.work)
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    env = environment()
    salsa = Path(args.mocap)
    sets = [a for item in args.set for a in ("--set", item)]
    summary = {}
    if args.corpus_budget > 0:
        data = work / "dance"
        config = work / "dance.yaml"
        cli = [sys.executable, "-m", "loosefit", "simulate"]
        preset = ["--preset", "tiny"] if args.tiny else ["--preset", "dance", "--bvh", str(salsa)]
        t0 = time.monotonic()
        subprocess.run([*cli, *preset, "--device", args.device, "--write-config", str(config)],
                       cwd=ROOT, env=env, check=True, capture_output=True)  # fmt: skip
        _set_cloth(config, args.set)
        cmd = [*cli, "--config", str(config), "--out", str(data), "--device", args.device,
               "--batch", str(args.corpus_batch),
               "--workers", str(args.corpus_workers)]  # fmt: skip
        if args.corpus_prepare_workers > 0:
            cmd += ["--prepare-workers", str(args.corpus_prepare_workers)]
        print(f"[{time.strftime('%H:%M:%S')}] corpus: {' '.join(cmd)}", flush=True)
        with open(out / "corpus.log", "w") as log:
            try:
                rc = subprocess.run(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
                                    timeout=args.corpus_budget).returncode  # fmt: skip
            except subprocess.TimeoutExpired:
                rc = "timeout"
        seconds = time.monotonic() - t0
        manifest = data / "manifest.json"
        m = json.loads(manifest.read_text()) if manifest.is_file() else {}
        done = [n for n, e in m.get("sequences", {}).items() if e.get("status") == "done"]
        flagged = [n for n, e in m.get("sequences", {}).items() if e.get("status") == "flagged"]
        frames = sum(e.get("frames", 0) for e in m.get("sequences", {}).values())
        summary = {"exit": rc, "seconds": seconds, "complete": m.get("complete", False),
                   "clips_done": len(done), "clips_flagged": flagged, "frames": frames,
                   "batch": args.corpus_batch, "workers": args.corpus_workers,
                   "summary": m.get("summary")}  # fmt: skip
        (out / "corpus.json").write_text(json.dumps(summary, indent=1) + "\n")
        if manifest.is_file():
            shutil.copyfile(manifest, out / "corpus_manifest.json")
        print(f"corpus: exit {rc} after {seconds:.0f} s, {len(done)} clips done, "
              f"{len(flagged)} flagged, {frames} frames", flush=True)  # fmt: skip
    left = t_end - time.monotonic()
    bench = [sys.executable, "bench/speed/sim_gpu.py", "--device", args.device, "--batches",
             args.batches, "--frames", str(args.frames), "--clips", str(args.clips),
             "--capture", args.capture, "--budget", str(max(left - 60, 0)),
             "--out", str(out), *sets]  # fmt: skip
    bench += ["--tiny"] if args.tiny else ["--bvh", str(salsa)]
    print(f"[{time.strftime('%H:%M:%S')}] table ({left:.0f} s left): {' '.join(bench)}", flush=True)
    try:
        rc = subprocess.run(bench, cwd=ROOT, env=env, timeout=max(left - 5, 1)).returncode
    except subprocess.TimeoutExpired:
        rc = "timeout"
    print(f"table: exit {rc}", flush=True)
    return 0 if rc == 0 and summary.get("exit", 0) == 0 else 1


def _set_cloth(config: Path, items: list[str]) -> None:
    """Change cloth fields of a written data set configuration (``KEY=VALUE``, JSON values)."""
    if not items:
        return
    text = config.read_text()
    import yaml

    data = yaml.safe_load(text)
    for item in items:
        key, _, value = item.partition("=")
        data["cloth"][key] = json.loads(value)
    config.write_text(yaml.safe_dump(data, sort_keys=False))


def build_kernels(cache: Path, arch: int = 90) -> int:
    """Compile, here, the warp modules a simulation loads, for the GPU's architecture
    (``sm_<arch>`` CUBINs, into the kernel cache ``cache``): a short simulation on the CPU
    loads every module of the solver, the contacts and the body, and each module it loaded
    is compiled ahead of time for the GPU (a module only a GPU loads is compiled there).
    On the device, warp finds them in its cache and compiles nothing whose source and
    options are the same. Returns the number of modules compiled."""
    code = f"""
import dataclasses, warp as wp
wp.init()
from loosefit.sim.driver import simulate_batch, settle
from loosefit.sim.presets import preset
from loosefit.sim.workers import Worker
from loosefit.sim.jobs import plan_jobs
config = preset("tiny")
worker = Worker.build(config)
jobs = plan_jobs(config)[:2]
motions = [worker.motion(j).slice(0, 2) for j in jobs]
cloth = dataclasses.replace(config.cloth, settle_seconds=0.04, blend_seconds=0.0)
for capture in (True, False):
    c = dataclasses.replace(cloth, capture=capture)
    simulate_batch(worker.avatar, worker.template, motions[:1], c)
    simulate_batch(worker.avatar, worker.template, motions, c, seeds=[0, 1])
settle(worker.avatar, worker.template, cloth, 30.0)
from warp._src.context import user_modules
done = 0
for name, module in list(user_modules.items()):
    if not module.kernels or not module.execs:  # only the modules the simulation loaded
        continue
    try:
        wp.compile_aot_module(module, arch={arch})
        done += 1
    except Exception as exc:
        print("not compiled:", name, type(exc).__name__, str(exc)[:200])
print("compiled", done)
"""
    env = dict(environment(), WARP_CACHE_PATH=str(cache))
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                          text=True)  # fmt: skip
    if done.returncode != 0:
        print(done.stdout[-2000:], done.stderr[-3000:])
        raise RuntimeError("building the kernel cache failed")
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("compiled")]
    return int(line[-1].split()[1]) if line else 0


# -- getting the packages and the clips there ------------------------------------------------


def pack(args: argparse.Namespace) -> int:
    """Download the device's missing wheels (Python 3.12, x86-64), bundle them with the salsa
    clips and split the bundle into parts in ``.gpu/``, each small enough to travel with the
    working tree in one call."""
    gpu = ROOT / ".gpu"
    wheels = gpu / "wheels"
    wheels.mkdir(parents=True, exist_ok=True)
    plat = [a for p in PLATFORMS for a in ("--platform", p)]
    for spec in WHEELS:
        name = spec.split("==")[0].replace("-", "_")
        if any(wheels.glob(f"{name}-*.whl")):
            continue
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:",
                        "--python-version", "3.12", "--implementation", "cp", *plat, "-d",
                        str(wheels), spec], check=True)  # fmt: skip
    cache = gpu / "warp-cache"
    if args.kernels and not (cache / "done").is_file():
        shutil.rmtree(cache, ignore_errors=True)
        n = build_kernels(cache, args.arch)
        (cache / "done").write_text(f"{n} modules for sm_{args.arch}\n")
        print(f"{n} warp modules compiled for sm_{args.arch} into {cache}")
    bundle = gpu / "bundle.tar.xz"
    with tarfile.open(bundle, "w:xz") as tar:
        tar.add(wheels, arcname="wheels")
        tar.add(Path(args.mocap), arcname="mocap")
        ballet = Path(args.mocap).parent / "cmu-ballet"
        if ballet.is_dir():  # the dance preset reads them beside the salsa folder
            tar.add(ballet, arcname="cmu-ballet")
        if args.kernels:
            tar.add(cache, arcname="warp-cache")
    for old in gpu.glob("part-*"):
        shutil.rmtree(old)
    data = bundle.read_bytes()
    # A part travels with the working tree: what git tracks, and what it neither tracks nor
    # ignores.
    listing = ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"]
    files = subprocess.run(listing, cwd=ROOT, capture_output=True, check=True).stdout.split(b"\0")
    tree = sum(
        (ROOT / f.decode()).stat().st_size for f in files if f and (ROOT / f.decode()).is_file()
    )
    size = CARRY_BYTES - tree
    if size < 4 * 2**20:
        print(f"the working tree is {tree / 2**20:.0f} MiB: too little room left to carry parts")
        return 1
    n = (len(data) + size - 1) // size
    for k in range(n):
        part = gpu / f"part-{k + 1}"
        part.mkdir()
        (part / f"{k + 1:02d}.bin").write_bytes(data[k * size : (k + 1) * size])
        meta = {"parts": n, "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}
        (part / "bundle.json").write_text(json.dumps(meta))
    bundle.unlink()
    print(f"{n} parts in {gpu}; on the device, one call each (carry ['.gpu/part-K']):")
    print("    python3 scripts/gpu_pipeline.py receive")
    print("then until it prints done:")
    print("    python3 scripts/gpu_pipeline.py run --budget 540 --out $OUT")
    return 0


def receive(args: argparse.Namespace) -> int:
    """Keep the carried part(s) on the device; once all are there, unpack and install."""
    parts = DEVICE_HOME / "parts"
    parts.mkdir(parents=True, exist_ok=True)
    meta = None
    for folder in sorted((ROOT / ".gpu").glob("part-*")):
        for f in folder.glob("*.bin"):
            shutil.copyfile(f, parts / f.name)
        meta = json.loads((folder / "bundle.json").read_text())
    if meta is None:
        print("no .gpu/part-K carried with this call")
        return 1
    have = sorted(parts.glob("*.bin"))
    if len(have) < meta["parts"]:
        print(f"{len(have)}/{meta['parts']} parts here: call again with the next")
        return 3
    data = b"".join(p.read_bytes() for p in have)
    if hashlib.sha256(data).hexdigest() != meta["sha256"]:
        print("the parts do not make the bundle (sha256 differs): pack again")
        return 1
    bundle = DEVICE_HOME / "bundle.tar.xz"
    bundle.write_bytes(data)
    with tarfile.open(bundle) as tar:
        tar.extractall(DEVICE_HOME, filter="data")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-index", "--no-deps",
                    "--no-compile", "--no-cache-dir", "--upgrade", "--target",
                    str(DEVICE_HOME / "site"), *map(str, (DEVICE_HOME / "wheels").glob("*.whl"))],
                   check=True)  # fmt: skip
    carried = DEVICE_HOME / "warp-cache"
    if carried.is_dir():  # the kernels compiled here for the GPU: into warp's default cache
        mine = Path.home() / ".cache" / "warp"
        for version in (p for p in carried.iterdir() if p.is_dir()):
            shutil.copytree(version, mine / version.name, dirs_exist_ok=True)
        print(f"warp's kernel cache: {mine}")
    print(f"installed into {DEVICE_HOME / 'site'}; clips in {DEVICE_HOME / 'mocap'}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("pack", help="here: the device's missing packages and the clips, in parts")
    p.add_argument("--mocap", default=str(ROOT.parent / "shared" / "mocap" / "cmu-salsa"))
    p.add_argument("--no-kernels", dest="kernels", action="store_false",
                   help="carry no kernels compiled here (the device compiles them)")  # fmt: skip
    p.add_argument("--arch", type=int, default=90, help="the GPU's sm_ (90: H100, H200)")
    sub.add_parser("receive", help="device: take a carried part; install once all are there")
    p = sub.add_parser("run", help="the next steps of the pipeline within a time budget")
    p.add_argument("--budget", type=float, default=540.0, help="seconds this call may take")
    p.add_argument("--work", default=str(DEVICE_HOME / "work"))
    p.add_argument("--out", default=os.environ.get("OUT", "out/gpu-pipeline"))
    p.add_argument("--device", default="cuda:0")
    p.add_argument("--mocap", default=str(DEVICE_HOME / "mocap"))
    p.add_argument("--batch", type=int, default=20, help="clips simulated at once")
    p.add_argument("--max-frames", type=int, default=None, help="frames kept per clip")
    p.add_argument("--generative-epochs", type=int, default=100)
    p.add_argument("--motion-epochs", type=int, default=60)
    p.add_argument("--precision", default="bf16", choices=("fp32", "bf16"))
    p.add_argument("--detail-epochs", type=int, default=4, help="dance: detail stage epochs")
    p.add_argument("--preset", default="paper", choices=("paper", "dance"),
                   help="paper: the paper-scale pipeline; dance: the dance set (the "
                   "dance data, the salsa set fine-tuned on it, Table 1 and 3 rows)")  # fmt: skip
    p.add_argument("--tiny", action="store_true", help="the tiny preset and a few epochs")
    p = sub.add_parser("sim-speed", help="the simulator on the GPU: the dance corpus, the table")
    p.add_argument("--budget", type=float, default=560.0, help="seconds this call may take")
    p.add_argument("--corpus-budget", type=float, default=240.0, help="0: no corpus run")
    p.add_argument("--corpus-batch", type=int, default=16)
    p.add_argument("--corpus-workers", type=int, default=2)
    p.add_argument("--corpus-prepare-workers", type=int, default=0,
                   help="processes preparing the corpus's motions (0: every core)")  # fmt: skip
    p.add_argument("--batches", default="1,8,32,64")
    p.add_argument("--frames", type=int, default=40)
    p.add_argument("--clips", type=int, default=8, help="distinct clips of the table")
    p.add_argument("--capture", default="on,substeps,off")
    p.add_argument("--set", action="append", default=[], help="cloth KEY=VALUE (JSON value)")
    p.add_argument("--device", default="cuda:0")
    p.add_argument("--mocap", default=str(DEVICE_HOME / "mocap"))
    p.add_argument("--work", default=str(DEVICE_HOME / "work"))
    p.add_argument("--out", default=os.environ.get("OUT", "out/sim-speed"))
    p.add_argument("--tiny", action="store_true", help="the tiny preset (a test's size)")
    args = ap.parse_args()
    commands = {"pack": pack, "receive": receive, "run": run, "sim-speed": sim_speed}
    return commands[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
