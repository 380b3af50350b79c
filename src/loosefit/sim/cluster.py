"""Making a data set on a Ray cluster: every clip a Ray task (docs/use/CLUSTER.md).

:func:`run_on_ray` is the executor :func:`loosefit.sim.generate.generate` uses when it is
given a :class:`ClusterConfig` instead of running its own processes. Each unit of work (a
clip, or a ``batch`` of clips) runs :func:`loosefit.sim.workers.run_clips` as a Ray task
on some node: the same function a local worker runs, so it simulates and writes the same
clip into the data set folder. The driver gathers the manifest as ``--workers`` does.

The data set folder must be the same path on every node (shared storage): each clip
saves its state there every ``resume_every`` frames, and a task whose worker dies is run
again by Ray, which goes on from the last save. A clip is in the data set only once its
sequence file is whole (written atomically) and the driver has recorded it.

Ray is an optional dependency: ``pip install 'loosefit[cluster]'``.
"""

from __future__ import annotations

import json
import os
import platform
import socket
import time
import urllib.parse
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from loosefit.errors import LoosefitInputError
from loosefit.sim.dataset_config import DatasetConfig
from loosefit.sim.jobs import Job, unit_name
from loosefit.sim.manifest import package_versions
from loosefit.sim.workers import run_clips

GCS_PORT = 6379  # a head's port when its address names none (ray start --head's default)
CLIENT_PORT = 10001  # the same for a Ray Client address (ray://HOST)


@dataclass
class ClusterConfig:
    """Which Ray cluster simulates the clips, and how.

    ``address`` is the head's "HOST:PORT" (what ``ray start --head`` prints),
    "ray://HOST:PORT" (Ray Client), "auto" (the cluster ``ray start`` runs on this machine),
    or None: RAY_ADDRESS, else that cluster, else a new Ray instance on this machine.
    """

    address: str | None = None  # the cluster's head: "HOST:PORT", "ray://HOST:PORT", "auto"
    connect_timeout: float = 5.0  # s to reach the head before giving up
    max_retries: int = 3  # times Ray runs a clip again whose worker or node died


class ClusterError(RuntimeError):
    """Clips whose Ray task failed (after Ray's retries); the others are in the data set."""


def import_ray():
    """The ``ray`` module, or an error that says how to install it."""
    try:
        import ray
    except ImportError:
        raise LoosefitInputError(
            "--ray",
            "ray",
            "the ray package: pip install 'loosefit[cluster]'",
            "it is not installed",
        ) from None
    return ray


def split_address(address: str) -> tuple[str, int]:
    """The host and port of a Ray address: ``HOST:PORT``, ``HOST`` (port 6379),
    ``ray://HOST[:PORT]`` (port 10001), ``[IPv6]:PORT``.

    Raises:
        LoosefitInputError: no host, or a port that is not a number.
    """
    client = address.startswith("ray://")
    rest = address.removeprefix("ray://")
    try:
        url = urllib.parse.urlsplit("//" + rest)
        host, port = url.hostname, url.port
    except ValueError:
        host = port = None
    if not host or "/" in rest.rstrip("/"):
        raise LoosefitInputError(
            "--ray", "address", "HOST:PORT of a Ray head (or ray://HOST:PORT)", repr(address)
        )
    return host, port or (CLIENT_PORT if client else GCS_PORT)


# An HTTP/2 client's opening (RFC 9113, 3.4) and an empty SETTINGS frame: a Ray head's
# services speak gRPC over HTTP/2, and answer with a SETTINGS frame (type 4) of their own.
_HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


def check_reachable(address: str, timeout: float) -> None:
    """Fail at once, naming ``address``, unless a gRPC server (a Ray head's) answers there
    within ``timeout`` seconds: Ray itself would retry for minutes.

    Raises:
        LoosefitInputError: naming the address and what answered there, if anything.
    """
    host, port = split_address(address)
    expected = (
        "the address of a running Ray cluster's head (`ray start --head` prints it; "
        "docs/use/CLUSTER.md)"
    )
    try:
        with socket.create_connection((host, port), timeout=timeout) as conn:
            conn.settimeout(timeout)
            conn.sendall(_HTTP2_PREFACE)
            head = b""
            while len(head) < 4 and (chunk := conn.recv(9 - len(head))):
                head += chunk
    except OSError as exc:
        raise LoosefitInputError(
            "--ray",
            "address",
            expected,
            f"nothing answering at {host}:{port} within {timeout:g} s ({exc or 'timed out'})",
        ) from None
    if len(head) < 4 or head[3] != 4:
        raise LoosefitInputError(
            "--ray",
            "address",
            expected,
            f"something at {host}:{port} that does not answer as a Ray "
            f"head (no gRPC server) within {timeout:g} s",
        )


def preflight(cluster: ClusterConfig) -> None:
    """Before any work: ray is installed and something answers at the cluster's address
    (:func:`check_reachable`). Seconds at most, where connecting would retry for minutes.

    Raises:
        LoosefitInputError: as :func:`import_ray` and :func:`check_reachable`.
    """
    import_ray()
    address = cluster.address or os.environ.get("RAY_ADDRESS") or None
    if address not in (None, "auto"):
        check_reachable(address, cluster.connect_timeout)


@contextmanager
def _env_default(name: str, value: str) -> Iterator[None]:
    """The environment variable ``name`` set to ``value`` meanwhile, unless it is set."""
    if name in os.environ:
        yield
        return
    os.environ[name] = value
    try:
        yield
    finally:
        os.environ.pop(name, None)


def _chain(exc: BaseException) -> list[BaseException]:
    """An exception and the ones it was raised from."""
    out = []
    while exc is not None and exc not in out:
        out.append(exc)
        exc = exc.__cause__ or exc.__context__
    return out


def connect(cluster: ClusterConfig, local_cpus: int | None = None) -> bool:
    """Connect this process to the cluster, or start a Ray instance on this machine
    (``local_cpus`` CPUs) where ``cluster.address`` is None and none runs here.

    Returns:
        Whether this call connected (the caller shuts Ray down after); False when this
        process was connected already (it stays so, and ``cluster.address`` is unused).

    Raises:
        LoosefitInputError: ray is not installed; the address is malformed or nothing
            answers there; the cluster refuses the connection (e.g. it asks for a token).
    """
    ray = import_ray()
    if ray.is_initialized():
        return False
    address = cluster.address or os.environ.get("RAY_ADDRESS") or None
    options = {"include_dashboard": False, "log_to_driver": False}
    try:
        if address in (None, "auto"):
            try:
                ray.init(address="auto", **options)
                return True
            except ConnectionError:
                if address == "auto":
                    raise
            ray.init(num_cpus=local_cpus, **options)
            cpus = ray.cluster_resources().get("CPU", 0)
            tqdm.write(f"no Ray cluster runs on this machine: started one with {cpus:g} CPUs")
            return True
        check_reachable(address, cluster.connect_timeout)
        # It answered: one try to join is enough, where Ray tries 20 times a second apart
        # (a cluster that refuses this machine's token: 1 s rather than 20 s).
        with _env_default("RAY_gcs_server_port_wait_time_s", "1"):
            ray.init(address=address, **options)
    except ConnectionError as exc:
        auth = any(
            "InvalidAuthToken" in str(e) or "AuthenticationError" in type(e).__name__
            for e in _chain(exc)
        )
        raise LoosefitInputError(
            "--ray",
            "address",
            "a Ray cluster that accepts this machine",
            f"{address}: {exc}",
            hint="it asks for a token: set RAY_AUTH_MODE=token and put the head's token "
            "(`ray get-auth-token` there) in ~/.ray/auth_token"
            if auth
            else None,
        ) from exc
    return True


def check_node(out_dir: Path, created: str, versions: dict[str, str]) -> None:
    """On a node: it sees the driver's data set folder, and runs the driver's packages.

    Args:
        out_dir: the data set folder, as the driver names it.
        created: the ``created`` stamp of the driver's manifest there.
        versions: the driver's :func:`~loosefit.sim.manifest.package_versions`.

    Raises:
        LoosefitInputError: naming the node: no such data set at that path (the folder is
            not on shared storage), or another version of a package.
    """
    node = platform.node()
    for attempt in range(3):  # a network file system may fail a read while the driver
        try:  # replaces the manifest: read again before refusing
            found = json.loads((out_dir / "manifest.json").read_text()).get("created")
        except (OSError, ValueError):
            found = None
        if found == created:
            break
        time.sleep(0.2 * (attempt + 1))
    if found != created:
        raise LoosefitInputError(
            out_dir,
            "manifest.json",
            f"the driver's data set (created {created}) at this path on every node: --out "
            "on storage the nodes share",
            f"{'none' if found is None else f'another one (created {found})'} on node {node}",
        )
    mine = package_versions()
    differ = sorted(k for k in versions if mine.get(k) != versions[k])
    if differ:
        raise LoosefitInputError(
            f"node {node}",
            "package versions",
            ", ".join(f"{k} {versions[k]}" for k in differ) + " (the driver's)",
            ", ".join(f"{k} {mine.get(k)}" for k in differ),
            hint="install the same loosefit, torch, newton and warp-lang on every node",
        )


def simulate_on_node(
    config: DatasetConfig,
    jobs: list[Job],
    out_dir: str,
    resume_every: int,
    created: str,
    versions: dict[str, str],
    *,
    cwd: str,
    progress,
) -> list[dict]:
    """A Ray task: :func:`check_node`, then :func:`~loosefit.sim.workers.run_clips` in
    the command's working directory ``cwd`` where the node has it (as a local worker
    runs), so that the configuration's relative paths name the same files."""
    check_node(Path(out_dir), created, versions)
    if Path(cwd).is_dir():
        os.chdir(cwd)
    return run_clips(config, jobs, out_dir, resume_every, progress)


def _drain(queue, on_progress: Callable[[str, int, int], None]) -> None:
    n = queue.qsize()
    if n:
        for item in queue.get_nowait_batch(n):
            on_progress(*item)


def run_on_ray(
    cluster: ClusterConfig,
    config: DatasetConfig,
    groups: list[list[Job]],
    out_dir: str,
    resume_every: int,
    created: str,
    *,
    on_progress: Callable[[str, int, int], None],
    record: Callable[[list[Job], list[dict]], None],
    local_cpus: int | None = None,
) -> None:
    """Simulate every unit of work as a Ray task (in ``groups``' order) and ``record``
    each as it finishes; progress reports come back as ``on_progress(name, frame, total)``.

    A task asks for one CPU (and one GPU where ``config.cloth.device`` is CUDA). Ray runs
    a task again whose worker or node died (``cluster.max_retries`` times), from the
    clip's last save in ``out_dir/resume``.

    Args:
        cluster: where to run.
        config: the data set's configuration.
        groups: the units of work (a clip each, or batches).
        out_dir: the data set folder, the same path on every node.
        resume_every: frames between a clip's saves.
        created: the manifest's ``created`` stamp (:func:`check_node`).
        on_progress: the driver's progress callback.
        record: the driver's callback for a finished unit and its manifest entries.
        local_cpus: the CPUs of a Ray instance started on this machine (:func:`connect`).

    Raises:
        LoosefitInputError: as :func:`connect`; a node that does not see the data set or
            runs other package versions (:func:`check_node`).
        ClusterError: naming the units whose task failed for good; the others are
            recorded, and the failed ones go on from their last save on a rerun.
    """
    ray = import_ray()
    started = connect(cluster, local_cpus)
    pending: list = []
    failed: list = []
    progress = None
    try:
        from ray.util.queue import Queue

        progress = Queue(actor_options={"num_cpus": 0})
        gpus = 1 if str(config.cloth.device).startswith("cuda") else 0
        task = ray.remote(
            num_cpus=1, num_gpus=gpus, max_retries=cluster.max_retries, retry_exceptions=False
        )(simulate_on_node)
        versions, cwd = package_versions(), os.getcwd()
        out_dir = str(Path(out_dir).resolve())  # the nodes' working directories differ
        units = {}
        for group in groups:
            ref = task.options(name=f"simulate {unit_name(group)}").remote(
                config, group, out_dir, resume_every, created, versions, cwd=cwd, progress=progress
            )
            units[ref] = group
        pending = list(units)
        while pending:
            done, pending = ray.wait(pending, num_returns=len(pending), timeout=0.2)
            _drain(progress, on_progress)
            for ref in done:
                try:
                    entries = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:  # raised by the clip's code
                    if isinstance(exc.cause, LoosefitInputError):  # the same on every node
                        raise exc.cause from None
                    failed.append((units[ref], exc))
                except ray.exceptions.RayError as exc:  # its worker or node died, retries spent
                    failed.append((units[ref], exc))
                else:
                    record(units[ref], entries)
        _drain(progress, on_progress)
    finally:
        for ref in pending:  # stopped early: the tasks left stop too (their saves stay)
            ray.cancel(ref, force=True)
        if progress is not None:
            progress.shutdown()
        if started:
            ray.shutdown()
    if failed:
        lines = [
            f"{unit_name(g)}: {type(e).__name__}: {str(e).strip().splitlines()[0][:200]}"
            for g, e in failed
        ]
        raise ClusterError(
            f"{len(failed)} of {len(groups)} unit(s) of work failed on the cluster:\n  "
            + "\n  ".join(lines)
            + f"\nthe rest is in {out_dir}; run the same command again to go on from their "
            f"last saves in {Path(out_dir) / 'resume'}"
        )
