"""The deterministic plan of every preset (cerberus_core.datasets.plan)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cerberus_core.bodies.body import source_class
from cerberus_core.datasets.plan import make_plan, preset_config
from cerberus_core.datasets.settings import GenerationConfig, SplitConfig


def _plan(config):
    return make_plan(config, source_class(config.dataset)())


def test_human_paper_preset_counts():
    plan = _plan(preset_config("human", "paper"))
    train, test = plan.totals("train"), plan.totals("test")
    assert train["quadruplets"] == 19_500 and train["images"] == 78_000
    assert test["images"] == 810 * 4 + 2 * 4  # 810 poses x 4 views + one canonical pose per test subject
    train_subjects = {s.name for s in plan.subjects if "train" in s.splits}
    test_subjects = {s.name for s in plan.subjects if "test" in s.splits}
    assert len(train_subjects) == 5 and len(test_subjects) == 2 and not train_subjects & test_subjects


def test_animal_paper_preset_counts():
    plan = _plan(preset_config("animal", "paper"))
    assert plan.totals("train")["quadruplets"] == 38_540
    assert plan.totals("train")["images"] == 41 * 47 * 4
    assert plan.totals("test")["images"] == 984
    assert len(plan.subjects) == 41 and all(s.splits == ("train", "test") for s in plan.subjects)
    # the same species, disjoint poses
    train_poses = {(m[0], m[1]) for sh in plan.shards["train"] for m in sh.meshes}
    test_poses = {(m[0], m[1]) for sh in plan.shards["test"] for m in sh.meshes}
    assert not train_poses & test_poses


@pytest.mark.parametrize("dataset", ["human", "animal", "primitives"])
@pytest.mark.parametrize("preset", ["small", "tiny"])
def test_presets_plan_and_are_deterministic(dataset, preset):
    a, b = _plan(preset_config(dataset, preset)), _plan(preset_config(dataset, preset))
    for split in a.shards:
        assert a.totals(split)["images"] > 0
        for sa, sb in zip(a.shards[split], b.shards[split], strict=True):
            np.testing.assert_array_equal(sa.views, sb.views)
            np.testing.assert_array_equal(sa.quads, sb.quads)
    c = _plan(preset_config(dataset, preset, seed=1))
    assert any(not np.array_equal(x.views, y.views) for x, y in zip(a.shards["train"], c.shards["train"], strict=True))


def test_pairs_share_viewpoints_across_poses_and_differ_across_pairs():
    plan = _plan(preset_config("primitives", "small"))
    azimuths = []
    for shard in plan.shards["train"]:
        v = shard.views
        for q in shard.quads:
            a0, a1, b0, b1 = v[q]
            assert a0["pose"] == a1["pose"] != b0["pose"] == b1["pose"] and a0["subject"] == b1["subject"]
            assert (a0["view"], a1["view"], b0["view"], b1["view"]) == (0, 1, 0, 1)
            assert a0["azimuth"] == b0["azimuth"] and a1["azimuth"] == b1["azimuth"]
            azimuths.append(a0["azimuth"])
    azimuths = np.array(azimuths)
    assert len(np.unique(azimuths)) == len(azimuths)  # a fresh random viewpoint per pair
    hist, _ = np.histogram(azimuths, bins=4, range=(0, 360))
    assert hist.min() > 0.15 * len(azimuths)  # roughly uniform


def test_grid_quadruplets_and_canonical_views():
    cfg = GenerationConfig("primitives", "t", {
        "train": SplitConfig("grid", subjects=2, poses=5, views=4, azimuths="shared", quadruplets_per_pose=3),
        "test": SplitConfig("grid", subjects=2, poses=3, views=8, canonical=True),
    })
    plan = _plan(cfg)
    for shard in plan.shards["train"]:
        v = shard.views
        assert len(shard.quads) == 2 * 15 and len(np.unique(shard.quads, axis=0)) == 30
        for q in shard.quads:
            a0, a1, b0, b1 = v[q]
            assert a0["pose"] == a1["pose"] != b0["pose"] == b1["pose"]
            assert a0["view"] == b0["view"] != a1["view"] == b1["view"]
            assert a0["azimuth"] == b0["azimuth"]  # shared azimuths: the same viewpoint for both poses
        for s in np.unique(v["subject"]):
            az = v["azimuth"][v["subject"] == s].reshape(-1, 4)
            assert (az == az[0]).all()
            np.testing.assert_allclose(np.diff(np.sort(az[0])), 90.0, atol=1e-3)
    test = np.concatenate([s.views for s in plan.shards["test"]])
    canon = test[test["canonical"]]
    assert len(canon) == 2 * 8 and set(canon["pose"]) == {0}
    np.testing.assert_allclose(canon["azimuth"][:8], np.arange(8) * 45.0)
    regular = test[~test["canonical"]].reshape(-1, 8)
    assert len(np.unique(regular["azimuth"][:, 0])) == len(regular)  # per-pose offsets


def test_splits_must_not_share_subjects():
    class Same(source_class("primitives")):
        def subjects(self, split, n, seed):
            return super().subjects("train", n, seed)

    cfg = preset_config("primitives", "tiny")
    with pytest.raises(ValueError, match="disjoint subjects"):
        make_plan(cfg, Same())


def test_every_bundled_dataset_preset_loads():
    from cerberus_core.datasets.plan import load_generation_config
    from cerberus_core.plugins import BODY_GROUP, plugin_names

    def sizes(dataset: str) -> list[str]:
        return source_class(dataset).sizes()

    assert sizes("human") == ["heldout_poses", "large", "paper", "small", "small128", "small_faithful", "tiny"]
    assert sizes("animal") == ["paper", "small", "small128", "small_faithful", "tiny"]
    assert sizes("primitives") == ["paper", "small", "tiny"]
    assert sizes("folder") == ["grid", "pairs"]
    assert {"human", "animal", "primitives", "folder"} <= set(plugin_names(BODY_GROUP))
    for dataset in plugin_names(BODY_GROUP):
        for size in sizes(dataset):
            cfg = load_generation_config(dataset, size)
            splits = ["test"] if (dataset, size) == ("human", "heldout_poses") else ["train", "test"]  # test only
            assert (cfg.dataset, cfg.preset, list(cfg.splits)) == (dataset, size, splits)
    human, prims = preset_config("human", "small").splits, preset_config("primitives", "small").splits
    assert human["train"].pose_pairs == "independent" and prims["train"].pose_pairs == "independent"
    # the default look (anti-aliased, framed, on black) and the paper's (look_paper.yaml)
    new, old = preset_config("human", "small"), preset_config("human", "small_faithful")
    assert (new.supersample, new.scene.fitted_radius, new.scene.background) == (4, 0.2, (0.0, 0.0, 0.0))
    assert (old.supersample, old.scene.fitted_radius, old.scene.background) == (1, None, (1.0, 1.0, 1.0))
    assert old.scene.distance > new.scene.distance
    assert preset_config("primitives", "small").supersample == 1
    assert prims == {**human, "train": replace(human["train"], pose_pairs="independent")}  # extends
    assert preset_config("animal", "paper").splits["train"] == SplitConfig(
        "grid", subjects=41, poses=47, views=4, azimuths="shared", quadruplets_per_pose=20)


def test_bad_configs_are_refused():
    with pytest.raises(ValueError, match="layout"):
        SplitConfig("triples")
    with pytest.raises(ValueError, match="2 views"):
        SplitConfig("grid", views=1, quadruplets_per_pose=2)
    with pytest.raises(ValueError, match="size = 'huge': unknown size preset"):
        preset_config("human", "huge")
    with pytest.raises(ValueError, match="image_size"):
        preset_config("human", "tiny", image_size=4)


def _pair_ids(plan, split="train"):
    """``(subject, pose a, pose b)`` of every quadruplet of a split."""
    return [(int(sh.views["subject"][q[0]]), int(sh.views["pose"][q[0]]), int(sh.views["pose"][q[2]]))
            for sh in plan.shards[split] for q in sh.quads]


def test_pose_pairs_mode_picks_the_pose_ids_and_only_motion_enters_the_config_hash():
    from cerberus_core.bodies.human_motion import MOTION_POSE_BASE
    from cerberus_core.datasets.format import config_hash
    from cerberus_core.datasets.plan import load_generation_config

    motion = load_generation_config("human", "tiny", ["splits.train.pose_pairs=motion"])
    independent = load_generation_config("human", "tiny")  # the human presets' default
    assert motion.splits["train"].pose_pairs == "motion" and independent.splits["train"].pose_pairs == "independent"
    base = MOTION_POSE_BASE
    assert _pair_ids(_plan(motion)) == [(0, base, base + 1), (0, base + 2, base + 3), (0, base + 4, base + 5),
                                        (0, base + 6, base + 7), (1, base, base + 1), (1, base + 2, base + 3),
                                        (1, base + 4, base + 5), (1, base + 6, base + 7)]
    assert _pair_ids(_plan(independent)) == [(s, 2 * k + 1, 2 * k + 2) for s in (0, 1) for k in range(4)]
    for a, b in zip(_plan(motion).shards["test"], _plan(independent).shards["test"], strict=True):
        np.testing.assert_array_equal(a.views, b.views)  # test grids are unaffected
    # Azimuths do not depend on the mode (the same draws of the plan's generator).
    np.testing.assert_array_equal(_plan(motion).shards["train"][0].views["azimuth"],
                                  _plan(independent).shards["train"][0].views["azimuth"])
    # `independent` is stored by omission: the config (and its hash) of a dataset from before the key.
    old_form = independent.to_dict()
    assert "pose_pairs" not in old_form["splits"]["train"] and "pose_pairs" not in old_form["splits"]["test"]
    assert motion.to_dict()["splits"]["train"]["pose_pairs"] == "motion"
    assert config_hash(motion.to_dict()) != config_hash(old_form)


def test_motion_pairs_are_refused_where_they_cannot_exist():
    from cerberus_core.datasets.plan import load_generation_config
    from cerberus_core.errors import ConfigError

    with pytest.raises(ConfigError, match="primitives source has no motion pose pairs.*pose_pairs=independent"):
        _plan(load_generation_config("primitives", "tiny", ["splits.train.pose_pairs=motion"]))
    with pytest.raises(ValueError, match="needs layout pairs"):
        SplitConfig("grid", poses=2, pose_pairs="motion")
    with pytest.raises(ValueError, match="pose_pairs"):
        load_generation_config("human", "tiny", ["splits.train.pose_pairs=video"])
    with pytest.raises(ConfigError, match="unlimited motion pairs"):
        source_class("human")().motion_pairs(source_class("human")().subjects("train", 1, 0)[0], "train", None)


def test_heldout_pose_set_shows_the_test_subjects_in_heldout_poses_and_only_heldout_enters_the_config_hash():
    from cerberus_core.bodies.human_heldout import HELDOUT_POSE_BASE
    from cerberus_core.datasets.format import config_hash
    from cerberus_core.datasets.plan import load_generation_config

    heldout, large = load_generation_config("human", "heldout_poses"), load_generation_config("human", "large")
    assert list(heldout.splits) == ["test"] and heldout.scene == large.scene
    assert heldout.supersample == large.supersample and heldout.seed == large.seed
    plan, standard = _plan(heldout), _plan(large)
    views, old = plan.shards["test"][0].views, standard.shards["test"][0].views
    assert plan.totals("test")["images"] == 2 * (36 + 1) * 4
    assert [s.name for s in plan.subjects] == [s.name for s in standard.subjects if "test" in s.splits]
    poses = sorted({int(p) for p in views["pose"][~views["canonical"]]})
    assert poses == [HELDOUT_POSE_BASE + k for k in range(36)]
    canonical = views[views["canonical"]]
    for key in ("pose", "view", "azimuth", "elevation", "distance", "fov_y"):  # Hard Human's images: the large set's
        np.testing.assert_array_equal(canonical[key], old[old["canonical"]][key])
    assert "pose_set" not in large.to_dict()["splits"]["test"]  # `sampled` is stored by omission
    assert heldout.to_dict()["splits"]["test"]["pose_set"] == "heldout"
    assert config_hash(heldout.to_dict()) != config_hash(replace(heldout, splits={
        "test": replace(heldout.splits["test"], pose_set="sampled")}).to_dict())
    with pytest.raises(ValueError, match="pose_set = 'heldout': needs layout grid"):
        SplitConfig(layout="pairs", pairs=2, pose_set="heldout")
    with pytest.raises(ValueError, match="the primitives source has no held-out poses; use `splits.test.pose_set=sampled`"):
        _plan(preset_config("primitives", "tiny", splits={"test": SplitConfig(layout="grid", subjects=1, poses=2,
                                                                                 pose_set="heldout")}))
