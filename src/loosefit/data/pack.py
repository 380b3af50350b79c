"""A data set folder packed small enough to share, and unpacked again, verified.

A pack is a plain tar, in one file or cut into pieces ``OUT.000``, ``OUT.001``, ... (its
bytes in order, :mod:`loosefit.data.pieces`), of the data set's files as they are but for
each clip ``sequences/NAME.npz``, which travels coded as ``sequences/NAME.npz.lfv``
(:mod:`loosefit.data.clip_codec`: garment_vertices quantised to 0.02 mm, so within 0.01 mm;
every other array exact). This is the format of the shared corpus's packer
(``../shared/datasets/lfz.py``), whose packs this module unpacks as that script does.

Packs made here add a first member, ``loosefit-pack.json`` (:data:`PACK_FORMAT`, the
step, and every other member's name, size and sha256), so that unpacking names any member
that is missing (a truncated pack or a lost last piece) or damaged. For a pack without it,
unpacking checks what the data set's manifest says: every clip of its split and every
simulated clip is there, each with the frames its entry counts.
"""

from __future__ import annotations

import hashlib
import io
import json
import lzma
import os
import re
import secrets
import shutil
import tarfile
import tempfile
import zipfile
import zlib
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from loosefit.data.clip_codec import CODED, STEP, decode_clip, encode_clip
from loosefit.data.pieces import PieceReader, PieceWriter, find_pieces
from loosefit.errors import LoosefitInputError

PACK_FORMAT = "loosefit.pack/1"
INDEX = "loosefit-pack.json"  # the first member of a pack made here
Progress = Callable[[int, int], None]


def _encode_file(path: Path, step: float) -> tuple[bytes, float, int]:
    """A sequence file -> its ``.lfv`` member, checked by decoding it: the largest vertex
    error (m) and the frame count."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise LoosefitInputError(path, "<file>", "a readable .npz", str(exc)) from exc
    if "garment_vertices" not in arrays:
        raise LoosefitInputError(path, "garment_vertices", "present", "missing")
    try:
        blob = encode_clip(arrays, step)
    except LoosefitInputError as exc:
        raise LoosefitInputError(path, exc.field, exc.expected, exc.found) from exc
    back = decode_clip(blob)
    gv = arrays["garment_vertices"]
    error = float(np.abs(back["garment_vertices"].astype(np.float64) - gv).max())
    bound = step / 2 + float(np.spacing(np.abs(gv).max()))  # float32's rounding on top
    same = all(
        np.array_equal(back[k], v) and back[k].dtype == v.dtype
        for k, v in arrays.items()
        if k != "garment_vertices"
    )
    if error > bound or not same or set(back) != set(arrays):  # (garment_vertices comes last)
        raise RuntimeError(
            f"{path}: the packed clip does not decode to the simulated one "
            f"(vertex error {error:.3g} m, bound {bound:.3g} m)"
        )
    return blob, error, len(gv)


# -- pack ----------------------------------------------------------------------------------


@dataclass
class PackReport:
    """What :func:`pack` wrote.

    Attributes:
        paths: the pack's files: one, or its pieces in order.
        files: the data set's files it holds.
        clips: of which clips (``sequences/*.npz``, coded).
        npz_bytes: the size of the data set's ``.npz`` files.
        packed_bytes: the pack's size.
        max_error: the largest distance of a decoded vertex from the simulated one (m).
        step: the quantisation step (m).
    """

    paths: list[Path]
    files: int
    clips: int
    npz_bytes: int
    packed_bytes: int
    max_error: float
    step: float

    @property
    def ratio(self) -> float:
        """How many times smaller than the ``.npz`` files the pack is."""
        return self.npz_bytes / max(self.packed_bytes, 1)


def dataset_files(root: Path) -> list[str]:
    """The files a pack of the data set ``root`` holds, as sorted POSIX paths relative to
    it: every file but the resume folder's, temporary ones (``.partial``) and a pack's
    index left by another unpacker."""
    names = []
    for p in sorted(Path(root).rglob("*")):
        rel = p.relative_to(root)
        if (
            not p.is_file()
            or rel.parts[0] == "resume"
            or ".partial" in p.name
            or rel.as_posix() == INDEX
        ):
            continue
        names.append(rel.as_posix())
    return names


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _encoded(paths: list[Path], step: float, workers: int) -> Iterator[tuple[bytes, float, int]]:
    """:func:`_encode_file` of each path, in order (on ``workers`` processes)."""
    if workers <= 1 or len(paths) <= 1:
        yield from (_encode_file(p, step) for p in paths)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield from pool.map(_encode_file, paths, [step] * len(paths))


def _numbered(out: Path) -> dict[int, Path]:
    """Pieces named ``OUT.NNN`` beside ``out``, by number."""
    pattern = re.compile(re.escape(out.name) + r"\.(\d+)")
    return {int(m.group(1)): f for f in out.parent.iterdir() if (m := pattern.fullmatch(f.name))}


def pack(
    source: str | Path,
    out: str | Path,
    piece_mib: float | None = None,
    workers: int = 1,
    step: float = STEP,
    progress: Progress | None = None,
) -> PackReport:
    """Pack the data set folder ``source`` into ``out`` (or its pieces ``out.000``, ...).

    Each clip is coded (:func:`encode_clip`) and decoded again to check it: its vertices
    within ``step / 2`` of the simulated ones (and float32's rounding), every other array
    exact. The pack is written beside ``out`` under a temporary name and renamed into
    place when whole; earlier pieces of that name beyond the new ones are removed.

    Args:
        source: a finished data set (``manifest.json``, ``template.npz``,
            ``sequences/*.npz``); its ``resume/`` folder and temporary files stay out.
        out: the pack's file (with ``piece_mib``: the prefix of its pieces).
        piece_mib: cut the pack into pieces of at most this many MiB.
        workers: processes coding the clips.
        step: the quantisation step of garment_vertices (m).
        progress: called as ``progress(done, total)`` over the data set's files.

    Raises:
        LoosefitInputError: not a finished data set, an unreadable clip, or a bad ``out``
            or ``piece_mib``.
    """
    from loosefit.data.format import DatasetReader

    root, out = Path(source), Path(out)
    DatasetReader(root)  # a finished data set, or an error saying what it lacks
    if piece_mib is not None and not piece_mib > 0:
        raise LoosefitInputError("--piece-mib", "piece_mib", "a size in MiB > 0", repr(piece_mib))
    folder = out.parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        found = "no such folder" if not folder.is_dir() else "not writable"
        raise LoosefitInputError(out, "<file>", "a path in a writable folder", found)
    if out.resolve().is_relative_to(root.resolve()):
        raise LoosefitInputError(out, "<file>", "a path outside the data set", "inside it")
    names = dataset_files(root)
    clips = [n for n in names if re.fullmatch(r"sequences/[^/]+\.npz", n)]
    report = PackReport([], len(names), len(clips), 0, 0, 0.0, step)
    report.npz_bytes = sum((root / n).stat().st_size for n in names if n.endswith(".npz"))
    limit = None if piece_mib is None else max(int(piece_mib * 2**20), 1)
    with tempfile.TemporaryDirectory(dir=folder, prefix=f".{out.name}.", suffix=".partial") as tmp:
        work = Path(tmp)
        # 1. Every member's bytes in the work folder: the clips coded (and checked), the
        #    other files copied (so that the index hashes what the tar holds).
        data: dict[str, Path] = {}
        coded = _encoded([root / n for n in clips], step, workers)
        for k, (name, (blob, error, _)) in enumerate(zip(clips, coded, strict=True)):
            data[name + CODED] = work / f"clip-{k:05d}"
            data[name + CODED].write_bytes(blob)
            report.max_error = max(report.max_error, error)
            if progress is not None:
                progress(k + 1, len(names))
        for k, name in enumerate(n for n in names if n not in set(clips)):
            data[name] = work / f"file-{k:05d}"
            shutil.copyfile(root / name, data[name])
            if progress is not None:
                progress(len(clips) + k + 1, len(names))
        members = [
            {"name": n, "size": p.stat().st_size, "sha256": _sha256(p)}
            for n, p in sorted(data.items())
        ]
        index = {"format": PACK_FORMAT, "step": step, "members": members}
        # 2. The tar: the index first, then the members as listed.
        writer = PieceWriter(work, limit)
        with tarfile.open(fileobj=writer, mode="w", format=tarfile.PAX_FORMAT) as tar:
            blob = json.dumps(index, indent=1).encode()
            tar.addfile(_info(INDEX, len(blob)), io.BytesIO(blob))
            for m in members:
                with open(data[m["name"]], "rb") as fh:
                    tar.addfile(_info(m["name"], m["size"]), fh)
        writer.close()
        # 3. Into place, whole.
        if limit is None:
            report.paths = [out]
        else:
            report.paths = [out.with_name(f"{out.name}.{k:03d}") for k in range(len(writer.paths))]
        for piece, final in zip(writer.paths, report.paths, strict=True):
            os.replace(piece, final)
    for k, stale in _numbered(out).items():
        if limit is None or k >= len(report.paths):
            stale.unlink()  # an earlier pack's: never taken for one of this pack's pieces
    report.packed_bytes = sum(p.stat().st_size for p in report.paths)
    return report


def _info(name: str, size: int) -> tarfile.TarInfo:
    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = size, 0o644, 0
    return info


# -- unpack --------------------------------------------------------------------------------


@dataclass
class UnpackReport:
    """What :func:`unpack` wrote.

    Attributes:
        dest: the data set folder.
        files: the files written.
        clips: of which clips decoded.
        pieces: the pack's files read.
        indexed: checked by the pack's index (a pack made here), else by its manifest.
    """

    dest: Path
    files: int
    clips: int
    pieces: list[Path]
    indexed: bool


# what a damaged member raises as it is decoded
_DAMAGE = (
    ValueError,
    TypeError,
    KeyError,
    IndexError,
    EOFError,
    OSError,
    OverflowError,
    lzma.LZMAError,
    zipfile.BadZipFile,
    zlib.error,
)


def _check_free(dest: Path) -> None:
    if dest.exists() and (not dest.is_dir() or any(dest.iterdir())):
        found = "a file" if not dest.is_dir() else f"{len(list(dest.iterdir()))} entries"
        raise LoosefitInputError(
            dest,
            "<folder>",
            "a new or empty folder",
            found,
            hint="choose another folder or remove it",
        )


def unpack(source: str | Path, dest: str | Path, progress: Progress | None = None) -> UnpackReport:
    """Unpack a pack (this module's, or the shared corpus packer's) into the data set folder
    ``dest``, verified.

    Everything is written into a temporary folder beside ``dest`` and renamed to it only
    when every member has been checked: by the pack's index (size and sha256 of each, none
    missing), or, for a pack without one, by its manifest (every clip of the split and
    every simulated clip there, with the frames its entry counts).

    Args:
        source: the pack's file, a folder of its numbered pieces, or their common prefix
            (``dance.lfz.`` for ``dance.lfz.000``, ``dance.lfz.001``).
        dest: a new or empty folder.
        progress: called as ``progress(done, total)`` over the members.

    Raises:
        LoosefitInputError: naming the pack's file (or piece) and the member: a missing
            piece, a truncated pack, a damaged member; or ``dest`` not empty.
    """
    pieces = find_pieces(source)
    dest = Path(dest)
    _check_free(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    # a folder of the permissions a new one gets (mkdtemp's are the owner's alone)
    work = dest.parent / f".{dest.name}.{os.getpid()}-{secrets.token_hex(4)}.partial"
    work.mkdir()
    try:
        files, clips, indexed = _extract(pieces, work, progress)
        _check_free(dest)
        if dest.exists():
            dest.rmdir()
        os.replace(work, dest)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return UnpackReport(dest, files, clips, pieces, indexed)


def _member_name(m: tarfile.TarInfo, piece: Path) -> str:
    """A member's name, if it is a regular file inside the data set folder."""
    parts = PurePosixPath(m.name).parts
    if not m.isfile() or not parts or m.name.startswith("/") or ".." in parts or "\\" in m.name:
        raise LoosefitInputError(
            piece, m.name, "a file inside the data set", "a link, folder or path outside it"
        )
    return m.name


def _extract(pieces: list[Path], work: Path, progress: Progress | None) -> tuple[int, int, bool]:
    """Every member into ``work``, checked; returns the files and clips written and whether
    the pack had an index."""
    stream = PieceReader(pieces)
    try:
        tar = tarfile.open(fileobj=io.BufferedReader(stream, 1 << 20), mode="r:")
    except tarfile.TarError as exc:
        stream.close()
        raise LoosefitInputError(
            pieces[0],
            "<first member>",
            "a pack (a tar of a data set's files)",
            f"none readable ({exc})",
        ) from None
    index: dict[str, dict] | None = None
    manifest: dict | None = None
    frames: dict[str, int] = {}  # each clip's decoded frame count
    seen: list[str] = []
    total = 1
    with tar, stream:
        while True:
            try:
                m = tar.next()
            except tarfile.TarError:  # cut or damaged after the last whole member: what is
                break  # missing is found below
            if m is None:
                break
            piece = stream.piece_at(m.offset_data)
            name = _member_name(m, piece)
            if name in seen or (name == INDEX and seen):
                raise LoosefitInputError(piece, name, "each member once", "it again")
            try:
                buf = tar.extractfile(m).read()
            except tarfile.TarError:
                raise LoosefitInputError(
                    stream.piece_at(stream.size),
                    name,
                    f"{m.size} bytes",
                    "fewer: the pack ends inside this member (truncated)",
                    hint="a piece may be missing or cut short",
                ) from None
            if name == INDEX:
                index = _read_index(buf, piece)
                total = len(index)
                seen.append(name)
                continue
            if index is not None:
                _check_member(index, name, buf, piece)
            target = work / (name[: -len(CODED)] if name.endswith(CODED) else name)
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                if name.endswith(CODED):
                    arrays = decode_clip(buf)
                    with open(target, "wb") as fh:
                        np.savez(fh, **arrays)
                    frames[PurePosixPath(target.name).stem] = len(arrays["garment_vertices"])
                else:
                    if name.endswith(".npz"):  # its CRCs checked by reading every array
                        with np.load(io.BytesIO(buf), allow_pickle=False) as z:
                            [z[k] for k in z.files]
                    if name == "manifest.json":
                        manifest = json.loads(buf)
                    target.write_bytes(buf)
            except _DAMAGE as exc:
                raise LoosefitInputError(
                    piece,
                    name,
                    "a member that decodes",
                    f"a damaged one ({type(exc).__name__}: {exc})",
                    hint="the pack is corrupted: fetch it again",
                ) from None
            seen.append(name)
            if index is None and manifest is not None:
                total = max(total, len(_needed(manifest)) + 2)
            if progress is not None:
                done = len(seen) - (index is not None)
                progress(done, max(total, done))
    last = pieces[-1]
    if index is not None:
        missing = [n for n in index if n not in seen]
        if missing:
            raise LoosefitInputError(
                last,
                missing[0],
                "every member the pack's index lists",
                f"{len(missing)} missing: the pack is truncated or damaged there",
                hint="a piece may be missing or cut short",
            )
    else:
        _check_by_manifest(manifest, seen, frames, last)
    return len(seen) - (index is not None), len(frames), index is not None


def _read_index(buf: bytes, piece: Path) -> dict[str, dict]:
    """A pack's index: its members by name."""
    try:
        index = json.loads(buf)
        fmt = index.get("format")
        members = {m["name"]: m for m in index["members"]}
        ok = fmt == PACK_FORMAT and all(
            isinstance(m["size"], int) and isinstance(m["sha256"], str) for m in members.values()
        )
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        raise LoosefitInputError(
            piece, INDEX, "the pack's index (JSON)", f"a damaged one ({exc})"
        ) from exc
    if not ok:
        raise LoosefitInputError(
            piece, INDEX, f"format {PACK_FORMAT!r}", repr(fmt), hint="a newer loosefit may read it"
        )
    return members


def _check_member(index: dict[str, dict], name: str, buf: bytes, piece: Path) -> None:
    entry = index.get(name)
    if entry is None:
        raise LoosefitInputError(piece, name, "a member the pack's index lists", "another")
    sha = hashlib.sha256(buf).hexdigest()
    if len(buf) != entry["size"] or sha != entry["sha256"]:
        raise LoosefitInputError(
            piece,
            name,
            f"{entry['size']} bytes of sha256 {entry['sha256'][:16]}...",
            f"{len(buf)} bytes of sha256 {sha[:16]}...: the member is corrupted",
            hint="fetch the pack again",
        )


def _needed(manifest: dict) -> set[str]:
    """The clips a data set's folder holds: those of its split and every one simulated
    there (a flagged clip's too; not one taken flagged from another data set)."""
    split = manifest.get("split", {}) if isinstance(manifest.get("split"), dict) else {}
    names = {n for key in ("train", "test") for n in split.get(key, []) if isinstance(n, str)}
    entries = manifest.get("sequences", {})
    entries = entries if isinstance(entries, dict) else {}
    for name, e in entries.items():
        if isinstance(e, dict) and (
            e.get("status") == "done" or ("quality" in e and "reused_from" not in e)
        ):
            names.add(name)
    return names


def _check_by_manifest(
    manifest: dict | None, seen: list[str], frames: dict[str, int], last: Path
) -> None:
    """A pack without an index is whole when its manifest's clips are all there, each with
    the frames its entry counts."""
    truncated = "missing: the pack is truncated or damaged"
    for name in ("manifest.json", "template.npz"):
        if name not in seen:
            raise LoosefitInputError(last, name, "a member of every data set", truncated)
    assert manifest is not None  # read with manifest.json
    entries = manifest.get("sequences", {})
    entries = entries if isinstance(entries, dict) else {}
    for clip in sorted(_needed(manifest)):
        member = f"sequences/{clip}.npz"
        if clip not in frames and member not in seen:
            raise LoosefitInputError(
                last, member + CODED, f"clip {clip}, which the manifest lists", truncated
            )
    for clip, count in sorted(frames.items()):
        want = entries.get(clip, {}).get("frames") if isinstance(entries.get(clip), dict) else None
        if isinstance(want, int) and want != count:
            raise LoosefitInputError(
                last,
                f"sequences/{clip}.npz{CODED}",
                f"{want} frames (the manifest's)",
                f"{count}: the member is damaged",
            )
