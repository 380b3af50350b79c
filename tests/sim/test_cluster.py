"""The Ray executor of the data set runner (loosefit.sim.cluster), on a Ray cluster the
tests start on this machine (``ray start --head``: two CPUs, so two workers, no dashboard)."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from loosefit.cli import main
from loosefit.data.format import DatasetReader, write_json_atomic
from loosefit.errors import LoosefitInputError
from loosefit.sim.cluster import (
    ClusterConfig,
    ClusterError,
    check_node,
    check_reachable,
    import_ray,
    split_address,
)
from loosefit.sim.generate import generate
from loosefit.sim.manifest import package_versions
from loosefit.sim.presets import preset

needs_ray = pytest.mark.skipif(
    importlib.util.find_spec("ray") is None,
    reason="ray is not installed (pip install 'loosefit[cluster]')",
)
# How a clip's run went rather than what it made: these may differ between two runs.
RUN_FIELDS = ("seconds", "seconds_per_frame", "resumed_frame")
RUN_SUMMARY = ("seconds_per_frame_mean", "clips_per_hour")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def head():
    """A one-node Ray cluster (the head's process, and its address), stopped afterwards."""
    script = Path(sys.executable).with_name("ray")
    ray_cli = str(script) if script.is_file() else shutil.which("ray")
    temp = tempfile.mkdtemp(prefix="lfray", dir="/tmp")  # short: Ray's socket paths are limited
    port = free_port()
    log = open(Path(temp) / "head.log", "w")  # noqa: SIM115 - open while the head runs
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAY_AUTH_MODE", "disabled")  # a cluster of this machine only, for the test
        mp.delenv("RAY_ADDRESS", raising=False)
        proc = subprocess.Popen(
            [
                ray_cli,
                "start",
                "--head",
                "--block",
                f"--port={port}",
                "--num-cpus=2",
                "--include-dashboard=false",
                f"--temp-dir={temp}",
                "--disable-usage-stats",
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=dict(os.environ),
        )
        try:
            deadline = time.monotonic() + 180
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    if proc.poll() is not None or time.monotonic() > deadline:
                        pytest.fail(f"ray start --head: {(Path(temp) / 'head.log').read_text()}")
                    time.sleep(0.2)
            yield proc, f"127.0.0.1:{port}"
        finally:
            proc.terminate()  # ray start --block stops the processes it started
            try:
                proc.wait(60)
            except subprocess.TimeoutExpired:
                proc.kill()
            log.close()
            shutil.rmtree(temp, ignore_errors=True)


@pytest.fixture(scope="module")
def local_tiny(tiny_simulated):
    """The tiny data set as the local runner makes it (one process, uninterrupted)."""
    return tiny_simulated


def assert_same_data_set(got: Path, want: Path) -> None:
    """The same manifest (but for how the runs went) and the same arrays, bit for bit."""
    a, b = (json.loads((p / "manifest.json").read_text()) for p in (got, want))
    assert a["complete"] and b["complete"]
    for key in ("format", "preset", "config", "versions", "body", "garment", "split", "excluded"):
        assert a[key] == b[key], key
    assert a["sequences"].keys() == b["sequences"].keys()
    for name in a["sequences"]:
        ea, eb = (
            {k: v for k, v in m["sequences"][name].items() if k not in RUN_FIELDS} for m in (a, b)
        )
        assert ea == eb, name
    assert {k: v for k, v in a["summary"].items() if k not in RUN_SUMMARY} == {
        k: v for k, v in b["summary"].items() if k not in RUN_SUMMARY
    }
    files = sorted(p.name for p in (want / "sequences").iterdir())
    assert sorted(p.name for p in (got / "sequences").iterdir()) == files
    for rel in ["template.npz", *(f"sequences/{f}" for f in files)]:
        with np.load(got / rel) as x, np.load(want / rel) as y:
            assert sorted(x.files) == sorted(y.files), rel
            for k in x.files:
                np.testing.assert_array_equal(x[k], y[k], err_msg=f"{rel}: {k}")


def _ancestors(pid: int) -> set[int]:
    out = set()
    while pid > 1:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            break
        pid = int(stat.rpartition(")")[2].split()[1])  # the field after the state: ppid
        out.add(pid)
    return out


def task_pids(head_pid: int, title: str) -> list[int]:
    """The processes of the test's cluster (under ``head_pid``) titled ``title``: Ray names
    a worker ``ray::TASK NAME`` while it runs a task."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
        except OSError:
            continue
        if cmd == title and head_pid in _ancestors(int(entry.name)):
            found.append(int(entry.name))
    return found


class Killer(threading.Thread):
    """Once ``clip``'s first save is in ``out/resume``, stops the worker simulating it, notes
    the saved frame and whether the clip's sequence was written, and kills the worker."""

    def __init__(self, head_pid: int, out: Path, clip: str) -> None:
        super().__init__(daemon=True)
        self.head_pid, self.out, self.clip = head_pid, out, clip
        self.done = threading.Event()
        self.killed: list[int] = []
        self.saved_frame = -1
        self.finished = None

    def run(self) -> None:
        save = self.out / "resume" / f"{self.clip}.npz"
        while not self.done.is_set():
            pids = task_pids(self.head_pid, f"ray::simulate {self.clip}") if save.is_file() else []
            if pids:
                for pid in pids:
                    os.kill(pid, signal.SIGSTOP)  # it writes nothing more
                with np.load(save) as saved:
                    self.saved_frame = int(saved["frame"])
                self.finished = (self.out / "sequences" / f"{self.clip}.npz").exists()
                for pid in pids:
                    os.kill(pid, signal.SIGKILL)
                self.killed = pids
                return
            time.sleep(0.02)


def run_with_kill(head, out: Path, clip: str, cluster: ClusterConfig):
    """``generate`` the tiny preset on the cluster, the worker of ``clip`` killed after its
    first save (every 2 frames of 24); the killer, and the ClusterError raised (or None)."""
    proc, _ = head
    killer = Killer(proc.pid, out, clip)
    killer.start()
    error = None
    try:
        generate(preset("tiny"), out, progress=False, resume_every=2, cluster=cluster)
    except ClusterError as exc:
        error = exc
    finally:
        killer.done.set()
        killer.join()
    assert killer.killed, f"no worker of {clip} was killed"
    assert killer.finished is False, f"{clip} was finished when its worker was killed"
    assert killer.saved_frame > 0
    return killer, error


@needs_ray
@pytest.mark.heavy
def test_a_killed_worker_s_clip_goes_on_from_its_save_and_the_data_set_is_the_local_one(
    head, local_tiny, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)  # --out relative to the command's folder, not the workers'
    out = Path("ray")
    killer, error = run_with_kill(head, out, "kick_000", ClusterConfig(head[1]))
    assert error is None
    # Ray ran the clip's task again, which went on from the save, not from the start
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["sequences"]["kick_000"]["resumed_frame"] >= killer.saved_frame
    assert "resumed_frame" not in manifest["sequences"]["spin_001"]
    assert_same_data_set(out, local_tiny)
    assert not list((out / "resume").glob("*.npz"))  # every save removed once its clip is whole


@needs_ray
@pytest.mark.heavy
def test_a_clip_whose_task_dies_for_good_is_missing_until_the_rerun_goes_on_from_its_save(
    head, local_tiny, tmp_path
):
    out = tmp_path / "ray"
    _, error = run_with_kill(head, out, "spin_001", ClusterConfig(head[1], max_retries=0))
    assert re.search(r"1 of 2 .*spin_001.*run the same command again", str(error), re.S)
    manifest = json.loads((out / "manifest.json").read_text())
    assert not manifest["complete"] and list(manifest["sequences"]) == ["kick_000"]
    assert not (out / "sequences" / "spin_001.npz").exists()  # nothing that looks whole
    with pytest.raises(LoosefitInputError, match="unfinished"):
        DatasetReader(out)
    saved = int(np.load(out / "resume" / "spin_001.npz")["frame"])
    manifest = generate(
        preset("tiny"), out, progress=False, resume_every=2, cluster=ClusterConfig(head[1])
    )
    assert manifest["sequences"]["spin_001"]["resumed_frame"] == saved
    assert_same_data_set(out, local_tiny)


@needs_ray
def test_an_address_where_no_cluster_answers_fails_at_once_naming_it(tmp_path, capsys):
    port = free_port()  # nothing listens there
    for address in (f"127.0.0.1:{port}", "no-such-host.invalid:6379"):
        with pytest.raises(LoosefitInputError, match=f"nothing answering at {address}"):
            generate(
                preset("tiny"),
                tmp_path / "a",
                progress=False,
                cluster=ClusterConfig(address, connect_timeout=2.0),
            )
    assert not (tmp_path / "a").exists()  # no data set begun
    with pytest.raises(LoosefitInputError, match="HOST:PORT"):
        generate(preset("tiny"), tmp_path / "a", progress=False, cluster=ClusterConfig("head:port"))
    # the command line: an error naming the address, no traceback
    out = tmp_path / "b"
    argv = ["simulate", "--preset", "tiny", "--out", str(out), "--ray", f"127.0.0.1:{port}"]
    assert main(argv) == 2
    assert f"nothing answering at 127.0.0.1:{port}" in capsys.readouterr().err
    assert not out.exists()


def test_a_port_that_does_not_speak_as_a_ray_head_is_refused_at_once():
    with socket.socket() as silent:  # the kernel accepts, nobody answers
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        address = f"127.0.0.1:{silent.getsockname()[1]}"
        with pytest.raises(LoosefitInputError, match=f"nothing answering at {address} within 1 s"):
            check_reachable(address, 1.0)
    with socket.socket() as other:  # another service: it says something else, and hangs up
        other.bind(("127.0.0.1", 0))
        other.listen()
        address = f"127.0.0.1:{other.getsockname()[1]}"

        def greet() -> None:
            conn, _ = other.accept()
            with conn:
                conn.sendall(b"SSH-2.0-OpenSSH_9.6\r\n")

        thread = threading.Thread(target=greet, daemon=True)
        thread.start()
        with pytest.raises(
            LoosefitInputError, match=f"something at {address} that does not answer as a Ray head"
        ):
            check_reachable(address, 5.0)
        thread.join()


def test_without_ray_the_error_says_how_to_install_it(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails
    with pytest.raises(LoosefitInputError, match=r"pip install 'loosefit\[cluster\]'"):
        import_ray()
    with pytest.raises(LoosefitInputError, match="not installed"):
        generate(preset("tiny"), tmp_path / "a", progress=False, cluster=ClusterConfig())
    assert not (tmp_path / "a").exists()


def test_addresses_are_read_as_ray_reads_them():
    assert split_address("10.0.0.5:6380") == ("10.0.0.5", 6380)
    assert split_address("head") == ("head", 6379)
    assert split_address("ray://head") == ("head", 10001)
    assert split_address("[fd00::2]:6379") == ("fd00::2", 6379)
    for bad in ("head:port", ":6379", "head:6379/x"):
        with pytest.raises(LoosefitInputError, match="HOST:PORT"):
            split_address(bad)


def test_a_node_that_does_not_see_the_data_set_or_runs_other_packages_says_so(tmp_path):
    write_json_atomic(tmp_path / "manifest.json", {"created": "2026-11-26T20:00:00+00:00"})
    versions = package_versions()
    check_node(tmp_path, "2026-11-26T20:00:00+00:00", versions)  # the driver's: fine
    with pytest.raises(LoosefitInputError, match="storage the nodes share.*none on node"):
        check_node(tmp_path / "elsewhere", "2026-11-26T20:00:00+00:00", versions)
    with pytest.raises(LoosefitInputError, match=r"another one \(created 2026-11-26T20:00"):
        check_node(tmp_path, "2026-11-27T09:00:00+00:00", versions)
    with pytest.raises(LoosefitInputError, match="newton 0.0.1 .the driver's.*same loosefit"):
        check_node(tmp_path, "2026-11-26T20:00:00+00:00", {**versions, "newton": "0.0.1"})


def test_without_ray_option_the_local_runner_runs(monkeypatch, tmp_path):
    """``simulate`` without ``--ray`` hands ``generate`` no cluster."""
    seen = {}

    def fake(config, out, **kw):
        seen.update(kw)
        raise SystemExit(0)

    import loosefit.sim.generate  # where loosefit.cli takes it from

    monkeypatch.setattr(loosefit.sim.generate, "generate", fake)
    with pytest.raises(SystemExit):
        main(["simulate", "--preset", "tiny", "--out", str(tmp_path / "x")])
    assert seen["cluster"] is None and seen["resume_every"] == 50
    with pytest.raises(SystemExit):
        main(["simulate", "--preset", "tiny", "--out", str(tmp_path / "x"), "--ray"])
    assert seen["cluster"] == ClusterConfig(address=None)
    with pytest.raises(SystemExit):
        main(["simulate", "--preset", "tiny", "--out", str(tmp_path / "x"), "--ray", "h:1"])
    assert seen["cluster"] == ClusterConfig(address="h:1")
