"""The inputs the fuzzing found breaking a reader (docs/design/RELIABILITY.md), kept as they were:
each now ends in a LoosefitInputError naming the file and the field."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import loosefit
from loosefit.errors import LoosefitInputError
from tests.conftest import WITH_DETAIL


def test_pc2_with_nan_and_a_missing_pc2(tmp_path):
    from loosefit.export import PC2_HEADER, read_pc2, write_pc2

    raw = bytearray(write_pc2(tmp_path / "a.pc2", np.zeros((3, 4, 3), np.float32)).read_bytes())
    raw[PC2_HEADER.size : PC2_HEADER.size + 4] = np.float32(np.nan).tobytes()
    (tmp_path / "a.pc2").write_bytes(bytes(raw))
    with pytest.raises(LoosefitInputError, match=r"a\.pc2.*points.*NaN.*\(0, 0, 0\)"):
        read_pc2(tmp_path / "a.pc2")
    with pytest.raises(LoosefitInputError, match=r"missing\.pc2.*readable"):
        read_pc2(tmp_path / "missing.pc2")


def test_an_obj_coordinate_beyond_float32(tmp_path):
    from loosefit.garment.obj import read_obj

    (tmp_path / "big.obj").write_text("v 3.4028235677973366e+38 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(LoosefitInputError, match=r"big\.obj.*line 1.*NaN/inf"):
        read_obj(tmp_path / "big.obj")


@pytest.mark.parametrize("text, field", [
    ("garment: nan dress, nan straps}\n", "garment"),
    ("garment:\n", "garment"),
    ("fps: fast\n", "fps"),
    ("motions: {specs: spin}\n", "motions.specs"),
    ("cloth: {self_contact: 1}\n", "cloth.self_contact"),
])  # fmt: skip
def test_config_values_of_the_wrong_kind(tmp_path, text, field):
    from loosefit.sim.dataset_config import read_config_file

    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(LoosefitInputError, match=rf"c\.yaml.*field '{field}'"):
        read_config_file(tmp_path / "c.yaml")


@pytest.mark.parametrize(
    "spec", ["dance:999999999999", "dance:1e400", "dance:-1", "speed:1e-9:spin", "speed:1000:spin"]
)
def test_motion_specs_that_ask_for_unbounded_memory(avatar, spec):
    from loosefit.motion.motions import load_motion

    with pytest.raises(LoosefitInputError, match="dance:SECONDS|speed:FACTOR"):
        load_motion(spec, avatar)


def test_npz_fields_of_another_kind(tmp_path, avatar, skirt):
    from loosefit.fitting.place import carry_rigidly
    from loosefit.sequence import GarmentSequence
    from loosefit.types import GarmentTemplate, Motion

    motion = avatar.rest_motion(2)
    g = carry_rigidly(skirt, avatar.pose_motion(motion), avatar).numpy()
    path = GarmentSequence(motion, skirt, g, {}, "t").save(tmp_path / "s.npz")
    good = dict(np.load(path))
    cases = [
        ("joint_names", np.array("Hips")),
        ("avatar", np.array([1.0, 2.0])),
        ("rotations", np.full(good["rotations"].shape, "x")),
        ("fps", np.array("30")),
    ]
    for field, value in cases:
        np.savez(path, **{**good, field: value})
        with pytest.raises(LoosefitInputError, match=rf"s\.npz.*{field}"):
            GarmentSequence.load(path)
    np.savez(path, **{**good, "name": np.array(["a", "b"])})
    with pytest.raises(LoosefitInputError, match=r"s\.npz.*name"):
        Motion.load(path)
    with pytest.raises(LoosefitInputError, match=r"s\.npz.*name"):
        GarmentTemplate.load(path)


@pytest.mark.parametrize(
    "key, value",
    [("split.train", None), ("body", None), ("body.floor_height", "high"), ("split", [1])],
)
def test_manifests_of_the_wrong_shape(tmp_path, toy_dataset, key, value):
    import shutil

    from loosefit.data.format import DatasetReader

    root = tmp_path / "ds"
    shutil.copytree(toy_dataset, root)
    manifest = json.loads((root / "manifest.json").read_text())
    *parents, last = key.split(".")
    target = manifest
    for p in parents:
        target = target[p]
    target[last] = value
    (root / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(
        LoosefitInputError, match=rf"manifest\.json.*{parents[0] if parents else key}"
    ):
        DatasetReader(root)


@pytest.mark.parametrize(
    "stage, key, value",
    [
        ("motion", "body", "\x9a"),
        ("detail", "fingerprints", None),
        ("motion", "rest_state", torch.zeros(2, 2)),
        ("generative", "garment", [1, 2]),
        ("detail", "format", {"x": 1}),
    ],
)
def test_checkpoint_fields_of_another_type(tmp_path, stage, key, value):
    from loosefit.inference.checkpoints import load_torch

    root = WITH_DETAIL  # a committed set with all three stages
    for name in ("generative", "motion", "detail"):
        (tmp_path / f"{name}.pt").write_bytes((root / f"{name}.pt").read_bytes())
    data = load_torch(root / f"{stage}.pt")
    data[key] = value
    torch.save(data, tmp_path / f"{stage}.pt")
    with pytest.raises(LoosefitInputError, match=rf"{stage}\.pt"):
        loosefit.load(tmp_path / "motion.pt")


def test_a_glb_whose_triangles_name_missing_vertices(tmp_path):
    import trimesh

    from loosefit.garment.importer import read_garment_mesh

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float64)
    raw = bytearray(
        trimesh.Trimesh(v, [[0, 1, 2], [1, 3, 2]], process=False).export(file_type="glb")
    )
    raw[645] = 1  # what the fuzzing changed: an index byte, now 256 of 4 vertices
    (tmp_path / "g.glb").write_bytes(bytes(raw))
    with pytest.raises(LoosefitInputError, match=r"g\.glb.*faces.*vertex indices below 4"):
        read_garment_mesh(tmp_path / "g.glb")
