import numpy as np
import pytest
import torch

from loosefit.data.format import DatasetReader
from loosefit.geometry.inverse_skinning import InverseSkinningConfig
from loosefit.train.frames import body_contacts, prepare_split
from tests.meshes import cube


@pytest.fixture(scope="module")
def reader(toy_dataset):
    return DatasetReader(toy_dataset)


@pytest.fixture(scope="module")
def prepared(reader, avatar):
    return prepare_split(reader, "train", avatar, InverseSkinningConfig(), max_frames=6)


def test_every_frame_of_the_split_in_its_root_frame(reader, prepared):
    assert prepared.names == ["a", "b"] and len(prepared) == 12 and prepared.fps == 30.0
    assert prepared.clip.tolist() == [0] * 6 + [1] * 6
    assert prepared.frame.tolist() == list(range(6)) * 2
    V = reader.template.num_vertices
    assert prepared.posed.shape == prepared.unposed.shape == (12, V, 3)
    assert prepared.heading.shape == (12, 3, 3) and prepared.origin.shape == (12, 3)
    assert prepared.contact_points is None and prepared.contact_normals is None
    # back into the world: the simulated garment
    world = prepared.world(torch.arange(12), prepared.posed)
    want = np.concatenate([reader.read(n).garment_vertices[:6] for n in ("a", "b")])
    torch.testing.assert_close(world, torch.from_numpy(want), atol=1e-5, rtol=0)
    # a heading is a turn about +Z
    H = prepared.heading
    torch.testing.assert_close(
        H @ H.transpose(1, 2), torch.eye(3).expand(12, 3, 3), atol=1e-5, rtol=0
    )
    torch.testing.assert_close(H[:, 2], torch.tensor([0.0, 0.0, 1.0]).expand(12, 3))


def test_the_unposed_targets_stay_near_the_template(reader, prepared):
    """The skirt is carried by the hips and swung at its hem: unskinned, its waist comes
    back to where the template has it."""
    template = torch.from_numpy(reader.template.vertices)
    waist = template[:, 2] > template[:, 2].max() - 0.01
    err = (prepared.unposed[:, waist] - template[waist]).norm(dim=-1)
    assert err.max() < 0.02


def test_contacts_when_asked(reader, avatar):
    with_contacts = prepare_split(reader, "test", avatar, max_frames=3, contacts=True)
    n = with_contacts.contact_normals
    assert with_contacts.contact_points.shape == n.shape == (3, reader.template.num_vertices, 3)
    length = n.norm(dim=-1)
    assert ((length - 1).abs() < 1e-4).logical_or(length == 0).all()


def test_body_contacts_of_points_about_a_box():
    v, f = cube()  # [-0.5, 0.5]^3
    body = np.stack([v, v + np.float32([0.0, 0.0, 1.0])])  # (T, 8, 3), raised at frame 1
    garment = np.array([[[0.0, 0.0, 0.55], [0.0, 0.0, 0.45], [0.0, 0.0, 0.8]]] * 2, np.float32)
    garment[1] += np.float32([0.0, 0.0, 1.0])
    points, normals = body_contacts(garment, body, f, reach=0.1)
    assert points.dtype == normals.dtype == np.float32
    for t in range(2):
        lift = np.float32([0.0, 0.0, t])
        np.testing.assert_allclose(points[t, :2], [[0, 0, 0.5] + lift] * 2, atol=1e-5)
        np.testing.assert_allclose(normals[t, :2], [[0, 0, 1]] * 2, atol=1e-5)
        # beyond the reach: no contact (a zero normal), the point left where it is
        np.testing.assert_array_equal(normals[t, 2], 0.0)
        np.testing.assert_allclose(points[t, 2], garment[t, 2])


def test_mirrored_frames_follow_each_clip(reader, avatar, prepared):
    """With ``mirror`` each clip is followed by itself mirrored left-right: the garment
    reflected onto its twin vertices in the root frame (a heading is a turn about +Z, so
    the root frame mirrors with the world), and unposed on the mirrored body."""
    from loosefit.motion.mirror import mirror_garment, vertex_twins

    both = prepare_split(
        reader, "train", avatar, InverseSkinningConfig(), max_frames=6, mirror=True
    )
    assert both.names == ["a", "a~mirror", "b", "b~mirror"] and len(both) == 24
    assert both.clip.tolist() == [0] * 6 + [1] * 6 + [2] * 6 + [3] * 6
    plain = both.clip.remainder(2) == 0
    torch.testing.assert_close(both.posed[plain], prepared.posed)
    torch.testing.assert_close(both.unposed[plain], prepared.unposed)
    twins = vertex_twins(reader.template.vertices)
    for i in (0, 2):
        clip, image = both.clip == i, both.clip == i + 1
        for field in ("posed", "unposed"):
            mirrored = torch.from_numpy(mirror_garment(getattr(both, field)[clip].numpy(), twins))
            gap = (getattr(both, field)[image] - mirrored).norm(dim=-1)
            # posed: exact; unposed: the body's seed points are symmetric to millimetres
            assert gap.max() < (1e-5 if field == "posed" else 0.01), (field, gap.max())
    # back into the world: the mirrored simulation
    world = both.world(torch.arange(24), both.posed)[both.clip == 1]
    want = mirror_garment(reader.read("a").garment_vertices[:6], twins)
    torch.testing.assert_close(world, torch.from_numpy(want), atol=1e-5, rtol=0)
