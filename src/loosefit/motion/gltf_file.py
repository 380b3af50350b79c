"""The glTF 2.0 container: its JSON, its buffers and its accessors (``.gltf``, ``.glb``).

:func:`read_document` reads a ``.glb`` (header, JSON chunk, binary chunk) or a ``.gltf``
(JSON; buffers embedded as base64 data URIs or in files beside it);
:func:`read_accessor` reads an accessor as a float array (any component type, byte
strides, normalized integers, sparse values). Every problem is a
:class:`~loosefit.errors.LoosefitInputError` naming the file and the JSON field
(``accessors[3].count``). :mod:`loosefit.motion.gltf` reads skins and animations with them.
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from loosefit.errors import LoosefitInputError

MAX_ELEMENTS = 10**7  # the most elements of an accessor that has no data (all zeros)

_COMPONENTS = {  # componentType -> (dtype, divisor when normalized)
    5120: (np.int8, 127.0),
    5121: (np.uint8, 255.0),
    5122: (np.int16, 32767.0),
    5123: (np.uint16, 65535.0),
    5125: (np.uint32, None),
    5126: (np.float32, None),
}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_GLB_JSON, _GLB_BIN = 0x4E4F534A, 0x004E4942
_UNREADABLE = ("EXT_meshopt_compression", "KHR_meshopt_compression")  # compressed buffers


@dataclass
class GltfDocument:
    """A parsed glTF: its JSON and its buffers' bytes."""

    path: Path
    gltf: dict
    buffers: list[bytes]


def gltf_error(doc_or_path, field: str, expected: str, found, hint: str | None = None):
    path = doc_or_path.path if isinstance(doc_or_path, GltfDocument) else doc_or_path
    return LoosefitInputError(path, field, expected, str(found), hint=hint)


def doc_list(doc: GltfDocument, key: str) -> list:
    items = doc.gltf.get(key, [])
    if not isinstance(items, list):
        raise gltf_error(doc, key, "a JSON array", type(items).__name__)
    return items


def doc_item(doc: GltfDocument, key: str, index, where: str) -> dict:
    items = doc_list(doc, key)
    if not (isinstance(index, int) and 0 <= index < len(items) and isinstance(items[index], dict)):
        raise gltf_error(doc, where, f"an index into '{key}' (0 to {len(items) - 1})", repr(index))
    return items[index]


# --------------------------------------------------------------------------- the file


def _read_buffers(path: Path, gltf: dict, glb_bin: bytes | None) -> list[bytes]:
    out = []
    buffers = gltf.get("buffers", [])
    if not isinstance(buffers, list):
        raise gltf_error(path, "buffers", "a JSON array", type(buffers).__name__)
    for i, buf in enumerate(buffers):
        where = f"buffers[{i}]"
        if not isinstance(buf, dict):
            raise gltf_error(path, where, "an object", repr(buf)[:40])
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or glb_bin is None:
                raise gltf_error(
                    path, f"{where}.uri", "a uri (only a GLB's first buffer has none)", "none"
                )
            data = glb_bin
        elif not isinstance(uri, str):
            raise gltf_error(path, f"{where}.uri", "a string", repr(uri)[:40])
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise gltf_error(path, f"{where}.uri", "a base64 data URI", head[:40])
            try:
                data = base64.b64decode(payload, validate=True)
            except (binascii.Error, ValueError) as exc:
                raise gltf_error(path, f"{where}.uri", "valid base64", str(exc)) from exc
        else:
            file = path.parent / unquote(uri)
            try:
                data = file.read_bytes()
            except OSError as exc:
                raise gltf_error(
                    path,
                    f"{where}.uri",
                    "a readable buffer file beside the glTF",
                    f"{file}: {exc.strerror}",
                ) from exc
        length = buf.get("byteLength")
        if not isinstance(length, int) or length < 0:
            raise gltf_error(path, f"{where}.byteLength", "a byte count", repr(length))
        if len(data) < length:
            raise gltf_error(
                path,
                f"{where}.byteLength",
                f"{length} bytes of data",
                f"{len(data)} bytes",
                hint="the file may be truncated",
            )
        out.append(data)
    return out


def read_document(path: Path) -> GltfDocument:
    """The JSON and buffers of a ``.gltf`` (buffers embedded or beside it) or a ``.glb``."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise gltf_error(path, "<file>", "a readable glTF file", exc.strerror or str(exc)) from exc
    glb_bin = None
    if raw[:4] == b"glTF":
        if len(raw) < 12:
            raise gltf_error(path, "GLB header", "12 bytes", f"{len(raw)} bytes")
        _, version, length = struct.unpack_from("<4sII", raw)
        if version != 2:
            raise gltf_error(path, "GLB header version", "2 (glTF 2.0)", version)
        if length > len(raw):
            raise gltf_error(
                path,
                "GLB header length",
                f"{length} bytes",
                f"{len(raw)} bytes in the file",
                hint="the file is truncated",
            )
        chunks, offset = [], 12
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, offset)
            if offset + 8 + size > length:
                raise gltf_error(
                    path,
                    f"GLB chunk {len(chunks)}",
                    f"{size} bytes",
                    f"{length - offset - 8}",
                    hint="the file is truncated",
                )
            chunks.append((kind, raw[offset + 8 : offset + 8 + size]))
            offset += 8 + size
        if not chunks or chunks[0][0] != _GLB_JSON:
            raise gltf_error(path, "GLB chunk 0", "the JSON chunk first", "another chunk or none")
        text = chunks[0][1]
        glb_bin = next((data for kind, data in chunks[1:] if kind == _GLB_BIN), None)
    elif path.suffix.lower() == ".glb":
        raise gltf_error(path, "GLB header", "the magic bytes 'glTF'", repr(raw[:4]))
    else:
        text = raw
    try:
        gltf = json.loads(text.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise gltf_error(path, "<json>", "UTF-8 JSON", str(exc)) from exc
    except json.JSONDecodeError as exc:
        raise gltf_error(path, "<json>", "valid JSON", f"{exc.msg} at line {exc.lineno}") from exc
    if not isinstance(gltf, dict):
        raise gltf_error(path, "<json>", "a JSON object", type(gltf).__name__)
    version = str((gltf.get("asset") or {}).get("version", ""))
    if not version.startswith("2"):
        raise gltf_error(
            path,
            "asset.version",
            "2.0 (glTF 2)",
            repr(version) if version else "none",
            hint="glTF 1.0 files: re-export as glTF 2.0",
        )
    required = [e for e in gltf.get("extensionsRequired", []) if e in _UNREADABLE]
    if required:
        raise gltf_error(
            path,
            "extensionsRequired",
            "no compressed buffers",
            required,
            hint="export again without mesh/animation compression",
        )
    return GltfDocument(path, gltf, _read_buffers(path, gltf, glb_bin))


def read_accessor(doc: GltfDocument, index, where: str) -> np.ndarray:
    """Accessor ``index`` as a (count, width) float64 array (normalized integers scaled)."""
    acc = doc_item(doc, "accessors", index, where)
    name = f"accessors[{index}]"
    count, ctype, kind = acc.get("count"), acc.get("componentType"), acc.get("type")
    if not isinstance(count, int) or count < 1:
        raise gltf_error(doc, f"{name}.count", "a positive count", repr(count))
    if ctype not in _COMPONENTS:
        raise gltf_error(doc, f"{name}.componentType", f"one of {list(_COMPONENTS)}", repr(ctype))
    if kind not in _WIDTHS:
        raise gltf_error(doc, f"{name}.type", f"one of {list(_WIDTHS)}", repr(kind))
    dtype, divisor = _COMPONENTS[ctype]
    dtype = np.dtype(dtype).newbyteorder("<")
    width = _WIDTHS[kind]
    if "bufferView" in acc:
        data = _view(
            doc, acc["bufferView"], acc.get("byteOffset", 0), count, width, dtype, where=name
        )
    elif count <= MAX_ELEMENTS:
        data = np.zeros((count, width), dtype)
    else:
        raise gltf_error(
            doc, f"{name}.count", f"at most {MAX_ELEMENTS} elements without a bufferView", count
        )
    sparse = acc.get("sparse")
    if isinstance(sparse, dict):  # a few values replaced
        data = data.copy()
        n, ind, val = sparse.get("count"), sparse.get("indices", {}), sparse.get("values", {})
        itype = _COMPONENTS.get(ind.get("componentType"), (None,))[0]
        if not (isinstance(n, int) and 0 < n <= count and itype is not None):
            raise gltf_error(
                doc, f"{name}.sparse", "a count and integer indices", repr(sparse)[:60]
            )
        idx = _view(
            doc,
            ind.get("bufferView"),
            ind.get("byteOffset", 0),
            n,
            1,
            np.dtype(itype).newbyteorder("<"),
            where=f"{name}.sparse.indices",
        )[:, 0]
        if idx.max() >= count:
            raise gltf_error(
                doc, f"{name}.sparse.indices", f"indices below {count}", int(idx.max())
            )
        data[idx] = _view(
            doc,
            val.get("bufferView"),
            val.get("byteOffset", 0),
            n,
            width,
            dtype,
            where=f"{name}.sparse.values",
        )
    out = data.astype(np.float64)
    if acc.get("normalized") and divisor is not None:
        out = np.maximum(out / divisor, -1.0)
    if not np.all(np.isfinite(out)):
        raise gltf_error(doc, name, "finite values", f"{int((~np.isfinite(out)).sum())} NaN or inf")
    return out


def _view(doc, index, offset, count: int, width: int, dtype: np.dtype, *, where: str) -> np.ndarray:
    """``count`` elements of ``width`` components from buffer view ``index``."""
    view = doc_item(doc, "bufferViews", index, f"{where}.bufferView")
    buffers = doc.buffers
    b = view.get("buffer")
    if not (isinstance(b, int) and 0 <= b < len(buffers)):
        raise gltf_error(
            doc, f"bufferViews[{index}].buffer", f"an index below {len(buffers)}", repr(b)
        )
    start = view.get("byteOffset", 0) + (offset if isinstance(offset, int) else 0)
    elem = dtype.itemsize * width
    stride = view.get("byteStride") or elem
    length = view.get("byteLength", 0)
    need = (start - view.get("byteOffset", 0)) + stride * (count - 1) + elem
    if need > length or start + stride * (count - 1) + elem > len(buffers[b]):
        raise gltf_error(
            doc,
            where,
            f"{count} elements of {elem} bytes inside bufferViews[{index}] ({length} bytes)",
            f"{need} bytes needed",
        )
    return np.ndarray(
        (count, width), dtype, buffer=buffers[b], offset=start, strides=(stride, dtype.itemsize)
    )


def doc_index(doc: GltfDocument, key: str, want: str | int | None, default: int, what: str) -> int:
    """The index of the item of ``key`` named ``want`` (or at that index); ``default`` when
    ``want`` is None."""
    items = doc_list(doc, key)
    names = [
        str(it.get("name", f"#{i}")) if isinstance(it, dict) else f"#{i}"
        for i, it in enumerate(items)
    ]
    if want is None:
        return default
    if str(want) in names:
        return names.index(str(want))
    if str(want).lstrip("-").isdigit() and 0 <= int(want) < len(items):
        return int(want)
    raise gltf_error(
        doc, key, f"the {what} named or numbered {want!r}", f"{len(items)}: {names[:10]}"
    )
