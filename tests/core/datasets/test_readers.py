"""The reader API the trainer and the evaluator code against (cerberus_core.datasets.readers)."""
from __future__ import annotations

import pickle

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import DatasetError
from cerberus_core.losses import background_mask
from cerberus_core.render.camera import Camera


def test_quadruplet_item_contract(pairs_dataset):
    ds = Dataset.open(pairs_dataset).quadruplets()
    assert len(ds) == 6 and ds.image_size == 32
    for i in range(len(ds)):
        item = ds[i]
        assert item["images"].shape == (4, 3, 32, 32) and item["images"].dtype == torch.float32
        assert 0.0 <= float(item["images"].min()) and float(item["images"].max()) <= 1.0
        for key in ("azimuth", "elevation", "distance", "fov_y"):
            assert item[key].shape == (4,) and item[key].dtype == torch.float32
        assert item["subject"].shape == () and item["subject"].dtype == torch.int64
        for key in ("pose", "view"):
            assert item[key].shape == (4,) and item[key].dtype == torch.int64
        pose, view, az = item["pose"], item["view"], item["azimuth"]
        assert pose[0] == pose[1] != pose[2] == pose[3]  # (a0, a1, b0, b1)
        assert view.tolist() == [0, 1, 0, 1]
        assert az[0] == az[2] and az[1] == az[3] and az[0] != az[1]
        assert torch.all(item["elevation"] == ds.scene.elevation)
        assert torch.all(item["distance"] == torch.tensor(ds.scene.distance, dtype=torch.float32))
        # the body is visible in every image, and not identical between viewpoints
        mask = background_mask(item["images"], ds.scene.background)
        assert bool((mask.mean((1, 2, 3)) < 0.99).all())
        assert not torch.equal(item["images"][0], item["images"][1])
    assert torch.equal(ds[-1]["images"], ds[len(ds) - 1]["images"])
    with pytest.raises(IndexError):
        ds[len(ds)]


def test_scene_and_cameras_helper(pairs_dataset):
    ds = Dataset.open(pairs_dataset).quadruplets()
    assert {"elevation", "distance", "fov_y", "ambient", "diffuse", "albedo", "background"} <= set(ds.scene.to_dict())
    batch = next(iter(DataLoader(ds, batch_size=3)))
    assert batch["images"].shape == (3, 4, 3, 32, 32)
    cam = ds.cameras(batch, slot=1)
    assert isinstance(cam, Camera) and cam.batch_size == 3 and cam.height == 32
    ref = Camera.look_at(batch["azimuth"][:, 1], batch["elevation"][:, 1], batch["distance"][:, 1],
                         fov_y_deg=batch["fov_y"][:, 1], image_size=32)
    torch.testing.assert_close(cam.rotation, ref.rotation)
    torch.testing.assert_close(cam.translation, ref.translation)
    every = ds.cameras(batch)
    assert every.batch_size == 12
    torch.testing.assert_close(every.rotation[1::4], cam.rotation)  # row-major (b, slot)
    light = ds.scene.light(cam)
    torch.testing.assert_close(light.direction, torch.nn.functional.normalize(cam.center, dim=-1))


def test_datasets_are_picklable_and_work_in_workers(pairs_dataset):
    ds = Dataset.open(pairs_dataset).quadruplets()
    _ = ds[0]  # opens memory maps, which must not travel
    clone = pickle.loads(pickle.dumps(ds))
    assert torch.equal(clone[2]["images"], ds[2]["images"])
    loaded = list(DataLoader(ds, batch_size=2, num_workers=2))
    images = torch.cat([b["images"] for b in loaded])
    assert torch.equal(images, torch.stack([ds[i]["images"] for i in range(len(ds))]))


def test_view_dataset_contract_gt_mesh_and_canonical(pairs_dataset):
    ds = Dataset.open(pairs_dataset).views()  # test split
    assert len(ds) == 12
    item = ds[3]
    assert item["images"].shape == (3, 32, 32)
    for key in ("azimuth", "elevation", "distance", "fov_y"):
        assert item[key].shape == () and item[key].dtype == torch.float32
    for key in ("subject", "pose", "view", "index"):
        assert item[key].dtype == torch.int64
    assert item["is_canonical"].dtype == torch.bool and int(item["index"]) == 3
    subjects = ds.subjects()
    assert len(subjects) == 1 and ds.subject_names[subjects[0]].startswith("test-")
    canon = ds.canonical_indices()
    assert list(canon) == subjects and len(canon[subjects[0]]) == 4
    for i in canon[subjects[0]]:
        assert bool(ds[i]["is_canonical"]) and int(ds[i]["pose"]) == 0
    assert [float(ds[i]["azimuth"]) for i in canon[subjects[0]]] == [0.0, 90.0, 180.0, 270.0]
    body = ds.gt_mesh(3)
    assert body.part_names == ds.part_names and body.vertex_parts.max() < len(ds.part_names)
    assert body.pose_id == int(item["pose"]) and body.subject == ds.subject_names[int(item["subject"])]
    same_pose = [i for i in range(len(ds)) if int(ds[i]["pose"]) == body.pose_id]
    assert len(same_pose) == 4 and all(np.array_equal(ds.gt_mesh(i).vertices, body.vertices) for i in same_pose)


def test_gt_mesh_is_regenerated_when_not_stored(tmp_path, pairs_config):
    from dataclasses import replace

    from cerberus_core.bodies.body import source_class
    from cerberus_core.datasets.dataset import Dataset

    cfg = pairs_config()
    cfg = replace(cfg, splits={**cfg.splits, "train": replace(cfg.splits["train"], meshes=False)})
    Dataset.generate(cfg, tmp_path / "ds", progress=False, log=lambda s: None)
    ds = Dataset.open(tmp_path / "ds").views("train")
    assert "vertices" not in ds.manifest.split("train").shards[0].files
    body = ds.gt_mesh(6)
    src = source_class("primitives")()
    (subject,) = [s for s in src.subjects("train", 2, 0) if s.name == body.subject]
    expected = src.bodies(subject, [body.pose_id])[0]
    np.testing.assert_array_equal(body.vertices, expected.vertices)


def test_grid_quadruplets_share_viewpoints(grid_dataset):
    ds = Dataset.open(grid_dataset).quadruplets()
    assert len(ds) == 2 * 6  # 2 subjects x min(3 pose pairs x 3 view pairs, 2 per pose x 3 poses)
    for i in range(len(ds)):
        it = ds[i]
        assert it["pose"][0] == it["pose"][1] and it["pose"][2] == it["pose"][3] and it["pose"][0] != it["pose"][2]
        assert it["view"][0] == it["view"][2] and it["view"][1] == it["view"][3] and it["view"][0] != it["view"][1]
        assert it["azimuth"][0] == it["azimuth"][2] and it["azimuth"][1] == it["azimuth"][3]


def test_wrong_split_or_kind_is_a_clear_error(pairs_dataset):
    with pytest.raises(DatasetError, match="no split 'val'.*test.*train"):
        Dataset.open(pairs_dataset).quadruplets("val")
    with pytest.raises(DatasetError, match=r"no quadruplets.*Dataset\.views"):
        Dataset.open(pairs_dataset).quadruplets("test")


def test_background_mask_is_exact(pairs_dataset):
    ds = Dataset.open(pairs_dataset).views()
    img = ds[0]["images"]
    mask = background_mask(img, ds.scene.background)
    assert mask.shape == (1, 32, 32)
    body = img[:, mask[0] == 0]
    assert float(body.max()) <= 0.8 + 1 / 255  # albedo * (ambient + diffuse)


def test_an_index_that_is_not_an_integer_is_named(pairs_dataset):
    """Issue 34 campaign: ``views["a"]`` was "'<' not supported between instances of 'str' and 'int'"."""
    from cerberus_core.errors import InputTypeError

    views = Dataset.open(pairs_dataset).views("test")
    with pytest.raises(InputTypeError, match=r"indexed by an integer 0..\d+, got str 'a'"):
        views["a"]
    assert views[np.int64(0)].keys() == views[0].keys()
