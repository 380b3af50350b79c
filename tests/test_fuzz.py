"""Property-based fuzzing of every reader: a malformed file ends in a LoosefitInputError
(naming the file) or in a correct result, never in another exception or an array with NaN.

Each test starts from a valid file and breaks it the ways real files break: truncated,
lines dropped or repeated, a token replaced by a number, NaN, inf, a huge value, text or
unicode, an array of another shape or dtype, a field missing. The CI profile tries a few
dozen cases per reader; ``LOOSEFIT_FUZZ=slow pytest tests/test_fuzz.py`` tries thousands
(docs/design/RELIABILITY.md).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import loosefit
from loosefit.errors import LoosefitInputError

settings.register_profile(
    "ci",
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
settings.register_profile(
    "slow",
    max_examples=1500,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("LOOSEFIT_FUZZ", "ci"))

# what a token of a text file is replaced by
WEIRD = st.sampled_from(
    [
        "nan",
        "NaN",
        "inf",
        "-inf",
        "1e400",
        "-1e308",
        "0",
        "-1",
        "3.5",
        "999999999999",
        "x",
        "",
        "１",
        "é",
        "\u202e",
        "1/2",
        "//",
        "-",
        "ROOT",
        "}",
        "{",
        "f",
        "v",
        "0x10",
    ]
)
TOKEN = st.one_of(WEIRD, st.text(max_size=6), st.floats().map(repr), st.integers().map(str))


def accepts(call):
    """Run a reader: a result, or None for its clear error; anything else fails the test."""
    try:
        return call()
    except LoosefitInputError as exc:
        assert str(exc), "an error with no message"
        return None


def finite(*arrays) -> None:
    for a in arrays:
        a = np.asarray(a)
        if a.dtype.kind == "f":
            assert np.isfinite(a).all(), "a result with NaN or infinity"


@st.composite
def broken_text(draw, text: str) -> str:
    """``text`` with a few of its lines dropped, repeated or with a token replaced, or cut."""
    lines = text.split("\n")
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["drop", "repeat", "token", "token", "token", "cut"]))
        if how == "drop":
            del lines[i]
        elif how == "repeat":
            lines.insert(i, lines[i])
        elif how == "cut":
            lines = lines[:i] + [lines[i][: draw(st.integers(0, len(lines[i])))]]
        else:
            words = lines[i].split(" ")
            j = draw(st.integers(0, len(words) - 1))
            words[j] = draw(TOKEN)
            lines[i] = " ".join(words)
    return "\n".join(lines)


def _write(tmp_path: Path, name: str, data: str | bytes) -> Path:
    path = tmp_path / name
    (path.write_bytes if isinstance(data, bytes) else path.write_text)(data)
    return path


# -- text formats ---------------------------------------------------------------------------


from tests.conftest import WITH_DETAIL  # noqa: E402
from tests.motion.test_bvh import chain_bvh  # noqa: E402

BVH = chain_bvh("ZXY")


@given(text=broken_text(BVH))
def test_bvh(tmp_path, text):
    from loosefit.motion.bvh import read_bvh

    clip = accepts(lambda: read_bvh(_write(tmp_path, "clip.bvh", text)))
    if clip is not None:
        finite(clip.offsets, clip.rotations, clip.local_translations, clip.frame_time)
        assert clip.rotations.shape[0] >= 1 and clip.frame_time > 0


OBJ = "\n".join(
    ["# a quad strip"]
    + [f"v {x} {y} 0" for y in (0.0, 0.5, 1.0) for x in (0.0, 0.5, 1.0)]
    + [f"vt {x} {y}" for y in (0.0, 0.5, 1.0) for x in (0.0, 0.5, 1.0)]
    + [f"f {a}/{a} {a + 1}/{a + 1} {a + 4}/{a + 4} {a + 3}/{a + 3}" for a in (1, 2, 4, 5)]
)


@given(text=broken_text(OBJ))
def test_obj(tmp_path, text):
    from loosefit.garment.importer import read_garment_mesh
    from loosefit.garment.obj import read_obj

    path = _write(tmp_path, "mesh.obj", text)
    mesh = accepts(lambda: read_obj(path, compute_uvs_if_missing=False))
    if mesh is not None:
        finite(mesh.vertices, mesh.uvs if mesh.uvs is not None else 0)
        assert mesh.faces.min() >= 0 and mesh.faces.max() < len(mesh.vertices)
    garment = accepts(lambda: read_garment_mesh(path))
    if garment is not None:
        finite(garment.vertices)


CONFIG = "garment: {type: dress, style: straps}\ncloth: {substeps: 8}\nmotions: {kind: specs, specs: [spin, kick], test: [kick]}\nfps: 30\n"  # noqa: E501


@given(text=broken_text(CONFIG))
def test_dataset_config_file(tmp_path, text):
    from loosefit.sim.dataset_config import read_config_file
    from loosefit.sim.jobs import plan_jobs

    config = accepts(lambda: read_config_file(_write(tmp_path, "d.yaml", text)))
    if config is not None:
        accepts(lambda: plan_jobs(config))


@given(
    spec=st.one_of(
        TOKEN,
        st.builds(
            "{}:{}".format,
            st.sampled_from(
                ["dance", "mirror", "speed", "speed:2", "speed:0", "speed:nan", "spin+", "dance:-1"]
            ),
            TOKEN,
        ),
    )
)
def test_motion_specs(avatar, spec):
    from loosefit.motion.motions import load_motion

    motion = accepts(lambda: load_motion(spec, avatar, max_frames=20))
    if motion is not None:
        finite(motion.rotations, motion.root_translation)
        assert motion.num_frames >= 1


# -- binary formats ---------------------------------------------------------------------------


@given(data=st.data())
def test_pc2(tmp_path, data):
    from loosefit.export import PC2_HEADER, read_pc2, write_pc2

    good = write_pc2(tmp_path / "good.pc2", np.zeros((3, 4, 3), np.float32)).read_bytes()
    raw = bytearray(good)
    how = data.draw(st.sampled_from(["cut", "bytes", "header", "nan"]))
    if how == "cut":
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    elif how == "bytes":
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    elif how == "header":
        i = data.draw(st.integers(12, PC2_HEADER.size - 4))
        raw[i : i + 4] = data.draw(st.binary(min_size=4, max_size=4))
    else:
        raw[PC2_HEADER.size : PC2_HEADER.size + 4] = np.float32(np.nan).tobytes()
    result = accepts(lambda: read_pc2(_write(tmp_path, "cache.pc2", bytes(raw))))
    if result is not None:
        finite(result[0], result[1], result[2])


def _arrays(draw, like: np.ndarray):
    """An array to put where ``like`` was: another shape or dtype, NaN, huge, empty, text."""
    how = draw(st.sampled_from(["shape", "dtype", "nan", "huge", "empty", "text", "scalar"]))
    if how == "shape":
        return np.zeros(tuple(draw(st.lists(st.integers(0, 5), max_size=4))), like.dtype)
    if how == "dtype" and like.dtype.kind in "fiub":
        return like.astype(
            draw(st.sampled_from([np.float64, np.int64, np.int8, np.bool_, np.complex64]))
        )
    if how == "nan" and like.dtype.kind == "f" and like.size:
        bad = like.copy()
        bad.flat[draw(st.integers(0, like.size - 1))] = draw(st.sampled_from([np.nan, np.inf]))
        return bad
    if how == "huge":
        return np.full(like.shape, 1e30 if like.dtype.kind == "f" else 2**40).astype(like.dtype)
    if how == "empty":
        return np.zeros((0,) + like.shape[1:], like.dtype)
    if how == "text":
        return np.array(draw(TOKEN))
    return np.array(draw(st.floats(allow_nan=True)))


@pytest.fixture(scope="module")
def sequence_file(tmp_path_factory, avatar, skirt):
    from loosefit.fitting.place import carry_rigidly
    from loosefit.sequence import GarmentSequence

    motion = avatar.rest_motion(3)
    g = carry_rigidly(skirt, avatar.pose_motion(motion), avatar).numpy()
    path = tmp_path_factory.mktemp("seq") / "good.npz"
    GarmentSequence(motion, skirt, g, {"rig": "cmu_mb", "shape": {}}, "test").save(path)
    return path


@given(data=st.data())
def test_sequence_template_and_motion_npz(tmp_path, sequence_file, data):
    from loosefit.sequence import GarmentSequence
    from loosefit.types import GarmentTemplate, Motion

    fields = dict(np.load(sequence_file))
    name = data.draw(st.sampled_from(sorted(fields)))
    if data.draw(st.booleans()):
        fields[name] = _arrays(data.draw, fields[name])
    else:
        del fields[name]
    path = tmp_path / "broken.npz"
    np.savez(path, **fields)
    seq = accepts(lambda: GarmentSequence.load(path))
    if seq is not None:
        finite(seq.garment_vertices, seq.motion.rotations, seq.garment.vertices)
    # the same fields read as a motion and as a template (their own names)
    renamed = {("name" if k == "motion_name" else k): v for k, v in fields.items()}
    np.savez(path, **renamed)
    motion = accepts(lambda: Motion.load(path))
    if motion is not None:
        finite(motion.rotations, motion.root_translation)
    template = accepts(lambda: GarmentTemplate.load(path))
    if template is not None:
        finite(template.vertices, template.uvs)
        assert template.faces.max() < template.num_vertices


@given(data=st.data())
def test_manifest(tmp_path, toy_dataset, data):
    import shutil

    from loosefit.data.format import DatasetReader

    root = tmp_path / "ds"
    if not root.exists():
        shutil.copytree(toy_dataset, root)
    manifest = json.loads((toy_dataset / "manifest.json").read_text())
    key = data.draw(
        st.sampled_from(
            [
                "format",
                "complete",
                "split",
                "body",
                "split.train",
                "split.test",
                "body.shape",
                "body.floor_height",
            ]
        )
    )
    value = data.draw(
        st.one_of(
            st.none(),
            st.booleans(),
            st.integers(),
            st.floats(),
            st.text(max_size=5),
            st.lists(st.text(max_size=3), max_size=3),
            st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
        )
    )
    target = manifest
    *parents, last = key.split(".")
    for p in parents:
        target = target[p]
    target[last] = value
    text = json.dumps(manifest)
    if data.draw(st.booleans()):
        text = text[: data.draw(st.integers(0, len(text)))]
    (root / "manifest.json").write_text(text)

    def read():
        reader = DatasetReader(root)
        for split in ("train", "test"):
            for name in reader.split(split):
                finite(reader.read(name).garment_vertices)
        return reader

    accepts(read)


@given(data=st.data())
def test_checkpoints(tmp_path, data):
    import torch

    from loosefit.inference.checkpoints import load_torch

    root = WITH_DETAIL  # a committed set with all three stages
    stage = data.draw(st.sampled_from(["generative", "motion", "detail"]))
    saved = load_torch(root / f"{stage}.pt")
    key = data.draw(st.sampled_from(sorted(saved)))
    how = data.draw(st.sampled_from(["delete", "value", "truncate"]))
    for name in ("generative", "motion", "detail"):
        (tmp_path / f"{name}.pt").write_bytes((root / f"{name}.pt").read_bytes())
    path = tmp_path / f"{stage}.pt"
    if how == "truncate":
        raw = path.read_bytes()
        path.write_bytes(raw[: data.draw(st.integers(0, len(raw) - 1))])
    else:
        if how == "delete":
            del saved[key]
        else:
            saved[key] = data.draw(
                st.one_of(
                    st.none(),
                    st.integers(),
                    st.text(max_size=4),
                    st.just(torch.full((2, 2), float("nan"))),
                    st.just({"x": 1}),
                    st.just([1, 2]),
                )
            )
        torch.save(saved, path)
    model = accepts(lambda: loosefit.load(tmp_path / "motion.pt").model)
    if model is not None:
        for p in model.encoder.parameters():
            finite(p.detach().numpy())


@given(data=st.data())
def test_glb(tmp_path, data):
    """A GLB (through trimesh) cut or with bytes changed."""
    import trimesh

    from loosefit.garment.importer import read_garment_mesh

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float64)
    good = trimesh.Trimesh(v, [[0, 1, 2], [1, 3, 2]], process=False).export(file_type="glb")
    raw = bytearray(good)
    if data.draw(st.booleans()):
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    else:
        for _ in range(data.draw(st.integers(1, 4))):
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    mesh = accepts(lambda: read_garment_mesh(_write(tmp_path, "g.glb", bytes(raw))))
    if mesh is not None:
        finite(mesh.vertices)
