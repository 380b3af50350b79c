"""Read a glTF 2.0 skinned skeleton and one of its animations (``.gltf``, ``.glb``).

What Blender, Mixamo (through Blender), Unity and Unreal export: a skin (its joints
are nodes of the scene), an animation whose channels drive those nodes' rotation,
translation and scale. The result is a :class:`~loosefit.body.bvh.BvhClip`, so the
retargeting and the joint matcher apply unchanged.

Quick start::

    clip = read_gltf("dance.glb", animation="Take 001")  # a BvhClip, glTF's axes
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height)

How a glTF becomes a clip:

* Joints: the skin's joints, ordered parents first; a joint's parent is its nearest
  ancestor node that is a joint. Skins whose joints hang from several roots get one
  more joint above them: their nearest common ancestor node, or ``"(scene root)"``.
* World transforms: every joint's, at each frame, through all its ancestor nodes
  (an ``Armature`` node's rotation and its scale of 0.01 included); the scene is
  glTF's: +Y up, facing +Z, metres.
* Rest pose: the skin's bind pose (the inverses of its ``inverseBindMatrices``),
  or the nodes' own transforms when the skin has none.
* The clip is a BVH-like skeleton whose frames are world-aligned at rest: a joint's
  rotation ``Q_j(t) = R_j(t) R_j(rest)^T`` (its world rotation from the rest pose; scale
  removed), local rotations ``Q_parent^T Q_j``, rest offsets from the rest positions,
  and local translations that put every joint where the glTF does.
* Frames: the animation is sampled at ``fps``, by default its keyframes' rate (the
  densest sampler's median spacing, rounded to a whole rate within 0.5 %) when that is
  at least :data:`MIN_KEY_FPS`, else :data:`DEFAULT_FPS`; from the first keyframe time
  to the last. ``LINEAR`` (rotations by slerp), ``STEP`` and ``CUBICSPLINE``
  interpolation; before the first key and after the last, the end values hold.
* A joint with a single child joint that is a leaf (Mixamo's ``HeadTop_End``, a
  ``_end`` tip) gets that child's offset as its End Site.
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

from loosefit.body.bvh import _UNIT_SCALES, BvhClip
from loosefit.body.rotations import _matrix_to_quat_f64, _slerp_f64, quat_to_matrix
from loosefit.errors import LoosefitInputError

GLTF_SUFFIXES = (".gltf", ".glb")
DEFAULT_FPS = 30.0  # sampling rate when the keyframes are too sparse to give one
MIN_KEY_FPS = 10.0  # keyframes at least this dense set the sampling rate
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")

_COMPONENTS = {  # componentType -> (dtype, divisor when normalized)
    5120: (np.int8, 127.0),
    5121: (np.uint8, 255.0),
    5122: (np.int16, 32767.0),
    5123: (np.uint16, 65535.0),
    5125: (np.uint32, None),
    5126: (np.float32, None),
}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_PATHS = {"translation": 3, "rotation": 4, "scale": 3}  # the channels read; weights are not
_GLB_JSON, _GLB_BIN = 0x4E4F534A, 0x004E4942
_UNREADABLE = ("EXT_meshopt_compression", "KHR_meshopt_compression")  # compressed buffers


@dataclass
class _Doc:
    """A parsed glTF: its JSON and its buffers' bytes."""

    path: Path
    gltf: dict
    buffers: list[bytes]


def _err(doc_or_path, field: str, expected: str, found, hint: str | None = None):
    path = doc_or_path.path if isinstance(doc_or_path, _Doc) else doc_or_path
    return LoosefitInputError(path, field, expected, str(found), hint=hint)


def _list(doc: _Doc, key: str) -> list:
    items = doc.gltf.get(key, [])
    if not isinstance(items, list):
        raise _err(doc, key, "a JSON array", type(items).__name__)
    return items


def _item(doc: _Doc, key: str, index, where: str) -> dict:
    items = _list(doc, key)
    if not (isinstance(index, int) and 0 <= index < len(items) and isinstance(items[index], dict)):
        raise _err(doc, where, f"an index into '{key}' (0 to {len(items) - 1})", repr(index))
    return items[index]


# --------------------------------------------------------------------------- the file


def _read_buffers(path: Path, gltf: dict, glb_bin: bytes | None) -> list[bytes]:
    out = []
    buffers = gltf.get("buffers", [])
    if not isinstance(buffers, list):
        raise _err(path, "buffers", "a JSON array", type(buffers).__name__)
    for i, buf in enumerate(buffers):
        where = f"buffers[{i}]"
        if not isinstance(buf, dict):
            raise _err(path, where, "an object", repr(buf)[:40])
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or glb_bin is None:
                raise _err(path, f"{where}.uri", "a uri (only a GLB's first buffer has none)",
                           "none")  # fmt: skip
            data = glb_bin
        elif not isinstance(uri, str):
            raise _err(path, f"{where}.uri", "a string", repr(uri)[:40])
        elif uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise _err(path, f"{where}.uri", "a base64 data URI", head[:40])
            try:
                data = base64.b64decode(payload, validate=True)
            except (binascii.Error, ValueError) as exc:
                raise _err(path, f"{where}.uri", "valid base64", str(exc)) from exc
        else:
            file = path.parent / unquote(uri)
            try:
                data = file.read_bytes()
            except OSError as exc:
                raise _err(path, f"{where}.uri", "a readable buffer file beside the glTF",
                           f"{file}: {exc.strerror}") from exc  # fmt: skip
        length = buf.get("byteLength")
        if not isinstance(length, int) or length < 0:
            raise _err(path, f"{where}.byteLength", "a byte count", repr(length))
        if len(data) < length:
            raise _err(path, f"{where}.byteLength", f"{length} bytes of data",
                       f"{len(data)} bytes", hint="the file may be truncated")  # fmt: skip
        out.append(data)
    return out


def _read_document(path: Path) -> _Doc:
    """The JSON and buffers of a ``.gltf`` (buffers embedded or beside it) or a ``.glb``."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise _err(path, "<file>", "a readable glTF file", exc.strerror or str(exc)) from exc
    glb_bin = None
    if raw[:4] == b"glTF":
        if len(raw) < 12:
            raise _err(path, "GLB header", "12 bytes", f"{len(raw)} bytes")
        _, version, length = struct.unpack_from("<4sII", raw)
        if version != 2:
            raise _err(path, "GLB header version", "2 (glTF 2.0)", version)
        if length > len(raw):
            raise _err(path, "GLB header length", f"{length} bytes",
                       f"{len(raw)} bytes in the file", hint="the file is truncated")  # fmt: skip
        chunks, offset = [], 12
        while offset + 8 <= length:
            size, kind = struct.unpack_from("<II", raw, offset)
            if offset + 8 + size > length:
                raise _err(path, f"GLB chunk {len(chunks)}", f"{size} bytes",
                           f"{length - offset - 8}", hint="the file is truncated")  # fmt: skip
            chunks.append((kind, raw[offset + 8 : offset + 8 + size]))
            offset += 8 + size
        if not chunks or chunks[0][0] != _GLB_JSON:
            raise _err(path, "GLB chunk 0", "the JSON chunk first", "another chunk or none")
        text = chunks[0][1]
        glb_bin = next((data for kind, data in chunks[1:] if kind == _GLB_BIN), None)
    elif path.suffix.lower() == ".glb":
        raise _err(path, "GLB header", "the magic bytes 'glTF'", repr(raw[:4]))
    else:
        text = raw
    try:
        gltf = json.loads(text.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise _err(path, "<json>", "UTF-8 JSON", str(exc)) from exc
    except json.JSONDecodeError as exc:
        raise _err(path, "<json>", "valid JSON", f"{exc.msg} at line {exc.lineno}") from exc
    if not isinstance(gltf, dict):
        raise _err(path, "<json>", "a JSON object", type(gltf).__name__)
    version = str((gltf.get("asset") or {}).get("version", ""))
    if not version.startswith("2"):
        raise _err(path, "asset.version", "2.0 (glTF 2)", repr(version) if version else "none",
                   hint="glTF 1.0 files: re-export as glTF 2.0")  # fmt: skip
    required = [e for e in gltf.get("extensionsRequired", []) if e in _UNREADABLE]
    if required:
        raise _err(path, "extensionsRequired", "no compressed buffers", required,
                   hint="export again without mesh/animation compression")  # fmt: skip
    return _Doc(path, gltf, _read_buffers(path, gltf, glb_bin))


def _accessor(doc: _Doc, index, where: str) -> np.ndarray:
    """Accessor ``index`` as a (count, width) float64 array (normalized integers scaled)."""
    acc = _item(doc, "accessors", index, where)
    name = f"accessors[{index}]"
    count, ctype, kind = acc.get("count"), acc.get("componentType"), acc.get("type")
    if not isinstance(count, int) or count < 1:
        raise _err(doc, f"{name}.count", "a positive count", repr(count))
    if ctype not in _COMPONENTS:
        raise _err(doc, f"{name}.componentType", f"one of {list(_COMPONENTS)}", repr(ctype))
    if kind not in _WIDTHS:
        raise _err(doc, f"{name}.type", f"one of {list(_WIDTHS)}", repr(kind))
    dtype, divisor = _COMPONENTS[ctype]
    dtype = np.dtype(dtype).newbyteorder("<")
    width = _WIDTHS[kind]
    if "bufferView" in acc:
        data = _view(doc, acc["bufferView"], acc.get("byteOffset", 0), count, width, dtype, name)
    else:
        data = np.zeros((count, width), dtype)
    sparse = acc.get("sparse")
    if isinstance(sparse, dict):  # a few values replaced
        data = data.copy()
        n, ind, val = sparse.get("count"), sparse.get("indices", {}), sparse.get("values", {})
        itype = _COMPONENTS.get(ind.get("componentType"), (None,))[0]
        if not (isinstance(n, int) and 0 < n <= count and itype is not None):
            raise _err(doc, f"{name}.sparse", "a count and integer indices", repr(sparse)[:60])
        idx = _view(doc, ind.get("bufferView"), ind.get("byteOffset", 0), n, 1,
                    np.dtype(itype).newbyteorder("<"), f"{name}.sparse.indices")[:, 0]  # fmt: skip
        if idx.max() >= count:
            raise _err(doc, f"{name}.sparse.indices", f"indices below {count}", int(idx.max()))
        data[idx] = _view(doc, val.get("bufferView"), val.get("byteOffset", 0), n, width, dtype,
                          f"{name}.sparse.values")  # fmt: skip
    out = data.astype(np.float64)
    if acc.get("normalized") and divisor is not None:
        out = np.maximum(out / divisor, -1.0)
    if not np.all(np.isfinite(out)):
        raise _err(doc, name, "finite values", f"{int((~np.isfinite(out)).sum())} NaN or inf")
    return out


def _view(doc, index, offset, count: int, width: int, dtype: np.dtype, where: str) -> np.ndarray:
    """``count`` elements of ``width`` components from buffer view ``index``."""
    view = _item(doc, "bufferViews", index, f"{where}.bufferView")
    buffers = doc.buffers
    b = view.get("buffer")
    if not (isinstance(b, int) and 0 <= b < len(buffers)):
        raise _err(doc, f"bufferViews[{index}].buffer", f"an index below {len(buffers)}", repr(b))
    start = view.get("byteOffset", 0) + (offset if isinstance(offset, int) else 0)
    elem = dtype.itemsize * width
    stride = view.get("byteStride") or elem
    length = view.get("byteLength", 0)
    need = (start - view.get("byteOffset", 0)) + stride * (count - 1) + elem
    if need > length or start + stride * (count - 1) + elem > len(buffers[b]):
        raise _err(doc, where, f"{count} elements of {elem} bytes inside bufferViews[{index}] "
                   f"({length} bytes)", f"{need} bytes needed")  # fmt: skip
    return np.ndarray((count, width), dtype, buffer=buffers[b], offset=start,
                      strides=(stride, dtype.itemsize))  # fmt: skip


# --------------------------------------------------------------------------- sampling


def sample_channel(
    times: np.ndarray, values: np.ndarray, interpolation: str, at: np.ndarray, rotation: bool
) -> np.ndarray:
    """A glTF animation sampler evaluated at given times.

    Args:
        times: (K,) non-decreasing keyframe times, seconds.
        values: (K, W) keyframe values, or (3K, W) for ``CUBICSPLINE`` (in-tangent,
            value, out-tangent per key); rotations are quaternions ``(x, y, z, w)``.
        interpolation: ``LINEAR``, ``STEP`` or ``CUBICSPLINE``.
        at: (T,) times to sample.
        rotation: the values are quaternions (slerp for ``LINEAR``, normalised).

    Returns:
        (T, W) float64 values; the first and last keys hold outside the keyframes.
    """
    times = np.asarray(times, np.float64)
    values = np.asarray(values, np.float64)
    K = len(times)
    if interpolation == "CUBICSPLINE":
        tangents_in, values, tangents_out = values[0::3], values[1::3], values[2::3]
    if K == 1:
        out = np.repeat(values[:1], len(at), axis=0)
    elif interpolation == "STEP":
        out = values[np.clip(np.searchsorted(times, at, side="right") - 1, 0, K - 1)]
    else:
        k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, K - 2)  # (T,) segment
        dt = times[k + 1] - times[k]
        s = np.clip((at - times[k]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)
        s = np.where(dt > 0, s, (at >= times[k + 1]).astype(np.float64))[:, None]  # (T, 1)
        v0, v1 = values[k], values[k + 1]
        if interpolation == "CUBICSPLINE":  # Hermite, glTF 2.0 appendix C
            s2, s3 = s * s, s * s * s
            d = dt[:, None]
            out = ((2 * s3 - 3 * s2 + 1) * v0 + (s3 - 2 * s2 + s) * d * tangents_out[k]
                   + (-2 * s3 + 3 * s2) * v1 + (s3 - s2) * d * tangents_in[k + 1])  # fmt: skip
        elif rotation:
            wxyz = _slerp_f64(np.roll(v0, 1, -1), np.roll(v1, 1, -1), s[:, 0])
            out = np.roll(wxyz, -1, -1)
        else:
            out = (1 - s) * v0 + s * v1
    if rotation:
        norm = np.linalg.norm(out, axis=-1, keepdims=True)
        out = np.where(norm > 1e-12, out / np.where(norm > 1e-12, norm, 1.0), [0, 0, 0, 1.0])
    return out


def _trs_matrix(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(T, 3) translations, (T, 4) quaternions (x, y, z, w), (T, 3) scales -> (T, 4, 4)."""
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = quat_to_matrix(np.roll(q, 1, -1)).astype(np.float64) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def _orthonormal(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) matrices -> the nearest rotations (scale and shear removed)."""
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    flip = np.linalg.det(r) < 0  # a mirroring scale: keep a proper rotation
    u[flip, :, 2] *= -1
    return np.where(flip[..., None, None], u @ vt, r)


# --------------------------------------------------------------------------- choosing


def _pick(doc: _Doc, key: str, want: str | int | None, default: int, what: str) -> int:
    """The index of the item of ``key`` named ``want`` (or at that index); ``default``."""
    items = _list(doc, key)
    names = [str(it.get("name", f"#{i}")) if isinstance(it, dict) else f"#{i}"
             for i, it in enumerate(items)]  # fmt: skip
    if want is None:
        return default
    if str(want) in names:
        return names.index(str(want))
    if str(want).lstrip("-").isdigit() and 0 <= int(want) < len(items):
        return int(want)
    raise _err(doc, key, f"the {what} named or numbered {want!r}",
               f"{len(items)}: {names[:10]}")  # fmt: skip


def gltf_animations(path: str | Path) -> list[str]:
    """The names of a glTF file's animations (``#i`` for unnamed ones), in file order."""
    doc = _read_document(Path(path))
    return [str(a.get("name", f"#{i}")) for i, a in enumerate(_list(doc, "animations"))]


# --------------------------------------------------------------------------- reading


def read_gltf(
    path: str | Path,
    animation: str | int | None = None,
    skin: str | int | None = None,
    fps: float | None = None,
    units: str = "auto",
    scale: float | None = None,
) -> BvhClip:
    """Read a glTF/GLB skin and animation into a :class:`BvhClip` (see the module's notes).

    Args:
        path: the ``.gltf`` or ``.glb`` file.
        animation: the animation's name or index (default: the first).
        skin: the skin's name or index (default: the skin whose joints the animation
            drives most, the first on a tie).
        fps: the sampling rate (default: the keyframes' rate, see the module's notes).
        units: ``"auto"`` or ``"m"`` (glTF is in metres), ``"cm"``, ``"mm"``.
        scale: metres per file unit; overrides ``units``.

    Returns:
        The clip, in glTF's axes (+Y up, facing +Z); ``meta`` names the animation,
        the skin, the rest pose used and the sampling rate.

    Raises:
        LoosefitInputError: naming the file and the field: a malformed file, no skin,
            no animation, an animation that drives none of the skin's joints, a name
            or index that is not there.
    """
    path = Path(path)
    try:
        return _read_gltf(_read_document(path), animation, skin, fps, units, scale)
    except LoosefitInputError:
        raise
    except (TypeError, KeyError, AttributeError, ValueError, IndexError) as exc:
        raise _err(path, "<json>", "a well-formed glTF 2.0 document",
                   f"{type(exc).__name__}: {exc}") from exc  # fmt: skip


def _read_gltf(doc: _Doc, animation, skin, fps, units, scale) -> BvhClip:
    path = doc.path
    nodes = _list(doc, "nodes")

    # 1. The animation and its channels on nodes.
    anims = _list(doc, "animations")
    if not anims:
        raise _err(doc, "animations", "an animation", "none in the file",
                   hint="export with animation on (Blender: glTF export > Animation)")  # fmt: skip
    a = _pick(doc, "animations", animation, 0, "animation")
    anim = _item(doc, "animations", a, f"animations[{a}]")
    anim_name = str(anim.get("name", f"#{a}"))
    channels: dict[tuple[int, str], tuple[np.ndarray, np.ndarray, str]] = {}
    samplers = anim.get("samplers", [])
    for c, ch in enumerate(anim.get("channels", [])):
        where = f"animations[{a}].channels[{c}]"
        target = ch.get("target", {}) if isinstance(ch, dict) else {}
        node, prop = target.get("node"), target.get("path")
        if prop not in _PATHS or node is None:
            continue  # morph weights, or an extension's pointer
        if not (isinstance(node, int) and 0 <= node < len(nodes)):
            raise _err(doc, f"{where}.target.node", f"a node index below {len(nodes)}", node)
        s = ch.get("sampler")
        if not (isinstance(s, int) and 0 <= s < len(samplers)):
            raise _err(doc, f"{where}.sampler", f"a sampler index below {len(samplers)}", s)
        sampler = samplers[s]
        swhere = f"animations[{a}].samplers[{s}]"
        interp = sampler.get("interpolation", "LINEAR")
        if interp not in INTERPOLATIONS:
            raise _err(doc, f"{swhere}.interpolation", f"one of {INTERPOLATIONS}", repr(interp))
        times = _accessor(doc, sampler.get("input"), f"{swhere}.input")[:, 0]
        values = _accessor(doc, sampler.get("output"), f"{swhere}.output")
        if np.any(np.diff(times) < 0):
            raise _err(
                doc,
                f"{swhere}.input",
                "increasing keyframe times",
                f"a time going back at key {int(np.argmax(np.diff(times) < 0)) + 1}",
            )
        keys = len(times) * (3 if interp == "CUBICSPLINE" else 1)
        if values.shape != (keys, _PATHS[prop]):
            raise _err(
                doc,
                f"{swhere}.output",
                f"{keys} values of {_PATHS[prop]} components ({prop}, {interp})",
                f"{values.shape[0]} of {values.shape[1]}",
            )
        channels[(node, prop)] = (times, values, interp)

    # 2. The skin and its joints, parents first.
    skins = _list(doc, "skins")
    if not skins:
        raise _err(
            doc,
            "skins",
            "a skinned skeleton (a skin)",
            "none in the file",
            hint="export the armature with its mesh (Blender: glTF export > Skinning)",
        )
    driven = {n for n, _ in channels}

    def joints_of(i: int) -> list[int]:
        js = _item(doc, "skins", i, f"skins[{i}]").get("joints", [])
        if not (isinstance(js, list) and js and all(isinstance(j, int) for j in js)
                and all(0 <= j < len(nodes) for j in js)):  # fmt: skip
            raise _err(doc, f"skins[{i}].joints", f"node indices below {len(nodes)}",
                       repr(js)[:60])  # fmt: skip
        return js

    best = max(range(len(skins)), key=lambda i: (len(driven & set(joints_of(i))), -i))
    k = _pick(doc, "skins", skin, best, "skin")
    skin_def, skin_joints = skins[k], joints_of(k)
    skin_name = str(skin_def.get("name", f"#{k}"))
    if not driven & set(skin_joints):
        raise _err(doc, f"animations[{a}].channels",
                   f"channels that drive the joints of skin '{skin_name}'",
                   f"animation '{anim_name}' drives none of its {len(skin_joints)} joints"
                   + (f" (it drives nodes {sorted(driven)[:8]})" if driven else ""),
                   hint="pick another --animation or skin")  # fmt: skip
    parent_node = _node_parents(doc, nodes)
    clip_nodes, parents, names = _joint_tree(doc, nodes, parent_node, skin_joints)

    # 3. Frame times.
    t0 = min(t[0] for t, _, _ in channels.values())
    t1 = max(t[-1] for t, _, _ in channels.values())
    fps, fps_how = _frame_rate(doc, channels, fps)
    T = int(np.floor((t1 - t0) * fps + 1e-6)) + 1
    at = t0 + np.arange(T) / fps  # (T,)

    # 4. World transforms of the joints and every node above them, at each frame and at rest.
    world: dict[int, np.ndarray] = {-1: np.broadcast_to(np.eye(4), (T, 4, 4))}
    rest: dict[int, np.ndarray] = {-1: np.eye(4)}
    for n in _with_ancestors(clip_nodes, parent_node):
        t, q, s = _node_trs(doc, nodes, n)  # (3,), (4,), (3,) the node's own transform
        rest[n] = rest[parent_node[n]] @ _trs_matrix(t[None], q[None], s[None])[0]
        sampled = []
        for prop, default in (("translation", t), ("rotation", q), ("scale", s)):
            if (n, prop) in channels:
                times, values, interp = channels[(n, prop)]
                sampled.append(sample_channel(times, values, interp, at, prop == "rotation"))
            else:
                sampled.append(np.broadcast_to(default, (T, len(default))))
        world[n] = world[parent_node[n]] @ _trs_matrix(*sampled)  # (T, 4, 4)
    ibm_how = "the nodes' own transforms (the skin has no inverseBindMatrices)"
    if skin_def.get("inverseBindMatrices") is not None:
        ibm = _accessor(doc, skin_def["inverseBindMatrices"], f"skins[{k}].inverseBindMatrices")
        if ibm.shape != (len(skin_joints), 16):
            raise _err(doc, f"skins[{k}].inverseBindMatrices",
                       f"{len(skin_joints)} MAT4 (one per joint)", f"{ibm.shape}")  # fmt: skip
        bind = np.linalg.inv(np.swapaxes(ibm.reshape(-1, 4, 4), -1, -2))  # column-major
        for n, b in zip(skin_joints, bind, strict=True):
            rest[n] = b
        ibm_how = "the skin's bind pose (inverseBindMatrices)"

    # 5. The clip: world-aligned rest frames, rotations from the rest pose.
    if scale is not None:
        if not (np.isfinite(scale) and scale > 0):
            raise _err(doc, "scale", "a positive factor", repr(scale))
        units_scale = float(scale)
    elif units == "auto":
        units_scale = 1.0  # glTF is in metres
    elif units in _UNIT_SCALES:
        units_scale = _UNIT_SCALES[units]
    else:
        raise _err(doc, "units", "one of 'auto', 'm', 'cm', 'mm'", repr(units))
    J = len(clip_nodes)
    pos = np.stack([world[n][:, :3, 3] for n in clip_nodes], 1) * units_scale  # (T, J, 3)
    rot = _orthonormal(np.stack([world[n][:, :3, :3] for n in clip_nodes], 1))  # (T, J, 3, 3)
    rest_pos = np.stack([rest[n][:3, 3] for n in clip_nodes]) * units_scale  # (J, 3)
    rest_rot = _orthonormal(np.stack([rest[n][:3, :3] for n in clip_nodes]))  # (J, 3, 3)
    Q = rot @ np.swapaxes(rest_rot, -1, -2)[None]  # (T, J, 3, 3) world rotation from rest
    local = Q.copy()
    trans = pos.copy()
    offsets = rest_pos.copy()
    for j in range(1, J):
        p = parents[j]
        local[:, j] = np.swapaxes(Q[:, p], -1, -2) @ Q[:, j]
        trans[:, j] = (np.swapaxes(Q[:, p], -1, -2) @ (pos[:, j] - pos[:, p])[..., None])[..., 0]
        offsets[j] = rest_pos[j] - rest_pos[p]
    children = [[c for c in range(J) if parents[c] == j] for j in range(J)]
    ends = {j: offsets[kids[0]].astype(np.float32) for j, kids in enumerate(children)
            if len(kids) == 1 and not children[kids[0]]}  # fmt: skip
    rot_channels = ("Xrotation", "Yrotation", "Zrotation")
    return BvhClip(
        path=path,
        joint_names=tuple(names),
        parents=np.asarray(parents, np.int64),
        offsets=offsets.astype(np.float32),
        channels=[("Xposition", "Yposition", "Zposition", *rot_channels)]
        + [rot_channels] * (J - 1),
        end_offsets=ends,
        rotations=local.astype(np.float32),
        local_translations=trans.astype(np.float32),
        frame_time=1.0 / fps,
        units_scale=units_scale,
        meta={
            "format": "glTF",
            "report": {
                "animation": f"'{anim_name}' ({a + 1} of {len(anims)}: "
                + ", ".join(repr(str(x.get("name", f"#{i}"))) for i, x in enumerate(anims))
                + ")",
                "skin": f"'{skin_name}' ({k + 1} of {len(skins)}), {len(skin_joints)} joints",
                "rest pose": ibm_how,
                "sampled": f"{fps:g} fps ({fps_how}), keyframes {t0:.3f} s to {t1:.3f} s",
            },
        },
    )


def _node_parents(doc: _Doc, nodes: list) -> dict[int, int]:
    """node -> its parent node, -1 for the scene's roots."""
    parent = dict.fromkeys(range(len(nodes)), -1)
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise _err(doc, f"nodes[{i}]", "an object", repr(node)[:40])
        for c in node.get("children", []):
            if not (isinstance(c, int) and 0 <= c < len(nodes)) or c == i or parent[c] >= 0:
                raise _err(doc, f"nodes[{i}].children", "indices of nodes with one parent each",
                           repr(c))  # fmt: skip
            parent[c] = i
    for i in range(len(nodes)):  # a cycle never reaches a root
        seen, n = set(), i
        while n >= 0:
            if n in seen:
                raise _err(doc, f"nodes[{i}]", "a tree of nodes", "a cycle of children")
            seen.add(n)
            n = parent[n]
    return parent


def _with_ancestors(joints: list[int], parent: dict[int, int]) -> list[int]:
    """The nodes and all their ancestors, each after its parent (``-1`` left out)."""
    out: list[int] = []
    for n in joints:
        chain = []
        while n >= 0 and n not in out and n not in chain:
            chain.append(n)
            n = parent[n]
        out.extend(reversed(chain))
    return out


def _joint_tree(doc: _Doc, nodes: list, parent: dict[int, int], joints: list[int]):
    """The clip's joints (node indices, -1 for a synthetic root), parents, unique names."""
    inside = set(joints)

    def joint_parent(n: int) -> int:
        p = parent[n]
        while p >= 0 and p not in inside:
            p = parent[p]
        return p

    roots = [n for n in joints if joint_parent(n) < 0]
    top = None
    if len(roots) > 1:  # one root above them: their nearest common ancestor, or the scene
        chains = []
        for r in roots:
            chain, n = [], parent[r]
            while n >= 0:
                chain.append(n)
                n = parent[n]
            chains.append(chain)
        common = [n for n in chains[0] if all(n in c for c in chains[1:])]
        top = common[0] if common else -1
    order: list[int] = []

    def visit(n: int) -> None:
        order.append(n)
        for c in joints:
            if joint_parent(c) == n:
                visit(c)

    if top is None:
        visit(roots[0])
    else:
        order.append(top)
        for r in roots:
            visit(r)
    index = {n: i for i, n in enumerate(order)}
    parents = [-1 if i == 0 else index.get(joint_parent(n), 0) for i, n in enumerate(order)]
    names: list[str] = []
    for n in order:
        name = "(scene root)" if n < 0 else str(nodes[n].get("name") or f"node{n}")
        names.append(name if name not in names else f"{name}#{n}")
    return order, parents, names


def _node_trs(doc: _Doc, nodes: list, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's own translation (3,), rotation (4,) as (x, y, z, w) and scale (3,)."""
    node = nodes[n]
    if "matrix" in node:
        try:
            m = np.asarray(node["matrix"], np.float64)
        except (TypeError, ValueError):
            m = np.full(1, np.nan)
        if m.shape != (16,) or not np.all(np.isfinite(m)):
            raise _err(doc, f"nodes[{n}].matrix", "16 finite numbers", repr(node["matrix"])[:60])
        m = m.reshape(4, 4).T  # column-major
        s = np.linalg.norm(m[:3, :3], axis=0)
        r = _orthonormal(m[:3, :3] / np.where(s > 0, s, 1.0))
        w, x, y, z = _matrix_to_quat_f64(r)
        return m[:3, 3], np.array([x, y, z, w]), s
    out = []
    for key, default in (("translation", [0, 0, 0]), ("rotation", [0, 0, 0, 1]),
                         ("scale", [1, 1, 1])):  # fmt: skip
        try:
            v = np.asarray(node.get(key, default), np.float64)
        except (TypeError, ValueError):
            v = np.full(1, np.nan)
        if v.shape != (len(default),) or not np.all(np.isfinite(v)):
            raise _err(doc, f"nodes[{n}].{key}", f"{len(default)} finite numbers",
                       repr(node.get(key))[:60])  # fmt: skip
        out.append(v)
    return out[0], out[1], out[2]


def _frame_rate(doc: _Doc, channels: dict, fps: float | None) -> tuple[float, str]:
    """The sampling rate and how it was chosen."""
    if fps is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise _err(doc, "fps", "a positive frame rate", repr(fps))
        return float(fps), "as asked"
    spacings = [np.median(np.diff(t)[np.diff(t) > 0]) for t, _, _ in channels.values()
                if np.any(np.diff(t) > 0)]  # fmt: skip
    if not spacings:
        return DEFAULT_FPS, "a single key: the default"
    rate = 1.0 / min(spacings)
    if rate < MIN_KEY_FPS:
        return DEFAULT_FPS, f"keyframes {rate:.3g} per second are sparse: the default"
    if abs(rate - round(rate)) < 0.005 * rate:
        rate = float(round(rate))
    return float(rate), "the keyframes' rate"
