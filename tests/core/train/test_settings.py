"""Training configs: presets, files with ``extends``, ``--set`` overrides, validation messages."""

import pytest
import yaml

from cerberus_core.config import parse_overrides
from cerberus_core.errors import ConfigError
from cerberus_core.train.settings import TrainConfig, config_diff, load_config, preset_names
from tests.support.paths import REPO


def test_bundled_presets_load_and_validate():
    assert {"paper", "cpu", "free_cerberus", "nmrr", "tiny"} <= set(preset_names())
    for name in preset_names():
        load_config(preset=name)


def test_paper_preset_has_the_papers_settings():
    c = load_config(preset="paper")
    assert (c.model.num_parts, c.model.sphere_level, c.model.width) == (9, 2, 64)
    assert (c.losses.recon, c.losses.translation, c.losses.background, c.losses.smoothness) == (1, 1, 1, 0.0001)
    assert c.losses.pose_consistency and c.losses.viewpoint_consistency
    assert (c.optim.lr, c.train.batch_size, c.train.steps) == (0.0005, 16, 100_000)
    assert config_diff(c, TrainConfig.from_dict({"data": {"num_workers": 4}, "train": {"log_every": 20,
                                                                                        "image_every": 2000}})) == []


def test_variant_presets_differ_from_paper_only_where_the_variant_says():
    paper = load_config(preset="paper")
    assert config_diff(paper, load_config(preset="free_cerberus")) == ["losses.pose_consistency"]
    nmrr = load_config(preset="nmrr")
    assert (nmrr.model.num_parts, nmrr.model.sphere_level, nmrr.model.rotation) == (1, 3, "none")
    assert nmrr.model.vertex_bound == 0.5 and load_config(preset="paper").model.vertex_bound is None
    assert not nmrr.losses.pose_consistency and nmrr.losses.smoothness > 0
    assert all(k.startswith(("model.", "losses.")) for k in config_diff(paper, nmrr))


def test_overrides_are_yaml_and_type_checked():
    c = load_config(preset="tiny", overrides=["optim.lr=5e-4", "losses.pose_consistency=false",
                                              "optim.betas=[0.8, 0.9]", "data.image_size=null"])
    assert c.optim.lr == 0.0005 and c.losses.pose_consistency is False
    assert c.optim.betas == [0.8, 0.9] and c.data.image_size is None
    assert parse_overrides(["a.b.c=1"]) == {"a": {"b": {"c": 1}}}
    with pytest.raises(ValueError, match="optim.lr: expected a number"):
        load_config(overrides=["optim.lr=fast"])
    with pytest.raises(ValueError, match=r"unknown config key.*model.parts.*model.num_parts"):
        load_config(overrides=["model.parts=3"])
    with pytest.raises(ValueError, match="section.key=value"):
        load_config(overrides=["optim.lr"])
    with pytest.raises(ValueError, match="train.on_nonfinite"):
        load_config(overrides=["train.on_nonfinite=ignore"])


def test_config_file_extends_a_preset_or_another_file(tmp_path):
    base = tmp_path / "base.yaml"
    base.write_text("extends: cpu\nmodel:\n  num_parts: 5\n")
    top = tmp_path / "top.yaml"
    top.write_text("extends: base.yaml\noptim:\n  lr: 0.001\n")
    c = load_config(top)
    cpu = load_config(preset="cpu")
    assert c.model.num_parts == 5 and c.optim.lr == 0.001 and c.data.image_size == cpu.data.image_size
    with pytest.raises(ValueError, match="unknown preset"):
        load_config(preset="huge")
    with pytest.raises(ValueError, match="does not exist"):
        load_config(tmp_path / "missing.yaml")


def test_variants_compose_with_a_schedule(tmp_path):
    """``extends: [cpu, nmrr]`` and ``--preset cpu --preset nmrr``: the CPU schedule with the NMRr
    changes; the paper settings both presets extend are applied once, first, and do not come back."""
    cpu = load_config(preset="cpu")
    both = load_config(preset=["cpu", "nmrr"])
    # nmrr also keeps the paper's cross view on the CPU schedule (whose Cerberus renders it with its own model)
    nmrr_changes = config_diff(load_config(preset="paper"), load_config(preset="nmrr"))
    assert config_diff(cpu, both) == sorted([*nmrr_changes, "losses.cross_view", "losses.cross_view_warmup"])
    assert (both.losses.cross_view, cpu.losses.cross_view) == ("partner", "own")
    assert (both.model.width, both.model.num_parts, both.train.steps) == (cpu.model.width, 1, cpu.train.steps)
    f = tmp_path / "exp.yaml"
    f.write_text("extends: [cpu, free_cerberus]\ntrain:\n  steps: 700\n")
    c = load_config(f)
    assert config_diff(cpu, c) == ["losses.pose_consistency", "train.steps"] and c.train.steps == 700
    assert load_config(preset=["nmrr", "cpu"]).model.num_parts == 1  # cpu says nothing of parts
    with pytest.raises(ValueError, match="unknown preset 'gpu'"):
        load_config(preset=["cpu", "gpu"])
    loop = tmp_path / "loop.yaml"
    loop.write_text("extends: loop.yaml\n")
    with pytest.raises(ValueError, match="deeper than 8"):
        load_config(loop)


def test_yaml_round_trip():
    c = load_config(preset="nmrr")
    import yaml
    assert TrainConfig.from_dict(yaml.safe_load(c.to_yaml())) == c


def test_table1_experiment_configs_load_and_say_what_their_names_say():
    """The configs behind docs/results.md stay loadable as the presets evolve; each holds the recipe
    only, and run.sh (which sets the dataset and the schedule per --scale) trains every one of them."""
    root = REPO / "experiments" / "table1"
    files = sorted(root.glob("*.yaml"))
    assert len(files) == 6
    script = (root / "run.sh").read_text()
    for f in files:
        c = load_config(f)
        dataset, variant = f.stem.split("_", 1)
        assert f.stem in script and "data:" not in f.read_text() and "\ntrain:" not in f.read_text()
        assert c.renderer == "warp" and c.model.width == 32
        assert c.losses.pose_consistency == (variant == "cerberus")
        assert c.model.num_parts == (1 if variant == "nmrr" else 9)


def test_errors_name_the_key_the_choices_and_the_closest_name():
    from cerberus_core.errors import ConfigError

    with pytest.raises(ConfigError, match=r"model.num_part'\] \(did you mean 'model.num_parts'\?\)"):
        load_config(overrides=["model.num_part=3"])
    with pytest.raises(ConfigError, match=r"optim.schedule: must be one of 'constant', 'cosine'.*mean 'cosine'"):
        load_config(overrides=["optim.schedule=cosin"])
    with pytest.raises(ConfigError, match=r"data.input_look: must be one of 'shaded', 'flat', 'random'"):
        load_config(overrides=["data.input_look=silhouette"])
    with pytest.raises(ConfigError, match=r"unknown preset 'cpx' \(did you mean 'cpu'\?\)"):
        load_config(preset="cpx")


def test_beyond_the_paper_switches_are_off_in_the_paper_presets_and_checked():
    for preset in ("paper", "paper_faithful"):
        c = load_config(preset=preset)
        assert (c.render.antialias, c.losses.silhouette, c.losses.chamfer, c.losses.hidden) == (False, 0.0, 0.0, 0.0)
    c = load_config(preset="cpu")
    assert (c.render.antialias, c.losses.silhouette, c.losses.chamfer, c.losses.hidden) == (True, 1.0, 0.1, 0.1)
    nmrr = load_config(preset=["cpu", "nmrr"])  # the baseline gets the same renderer and terms
    assert (nmrr.model.num_parts, nmrr.render.antialias, nmrr.losses.silhouette) == (1, True, 1.0)
    with pytest.raises(ValueError, match="losses.silhouette needs render.antialias: true"):
        load_config(preset="paper_faithful", overrides=["losses.silhouette=1"])


@pytest.mark.parametrize(("text", "words"), [
    ("a: 1\na: 2\n", "f.yaml:2: not valid YAML (the key 'a' is given twice (lines 1 and 2); keep one)"),
    ("{a: 1, a: 2}", "the key 'a' is given twice (line 1)"),
    ("? [1, 2]\n: 3\n", "a list is used as a key"),
    ("? {a: 1}\n: 3\n", "a mapping is used as a key"),
    ("[" * 100_000, "nested deeper than 16 levels"),
    ("a:\n" + "".join("  " * i + f"b{i}:\n" for i in range(1, 40)), "f.yaml:16: not valid YAML (nested deeper"),
    ("steps: " + "9" * 5000, "f.yaml: not valid YAML (a number of more than 4300 digits)"),  # was a ValueError
])
def test_one_strict_reader_for_every_config_text(text, words):
    """Issue 34: files, presets, saved configs and ``--set`` values are read by one reader; a duplicate key, a
    list or mapping as a key and absurd nesting are each one ConfigError line (no TypeError, RecursionError)."""
    from cerberus_core.config import load_yaml

    with pytest.raises(ConfigError) as caught:
        load_yaml(text, "f.yaml")
    assert words in str(caught.value) and "\n" not in str(caught.value)
    value = text.replace("\n", " ") if text.startswith("{") or text.startswith("[") else None
    if value is not None:  # the same text as a --set value
        with pytest.raises(ConfigError, match="overrides = .*: the value is not valid YAML"):
            load_config(preset="tiny", overrides=[f"train.steps={value}"])


def test_a_config_section_with_a_number_as_key_is_an_unknown_key():
    with pytest.raises(ConfigError, match=r"unknown config key\(s\) \['data.1', 'data.x'\]"):
        load_config(preset="tiny", overrides=["data={1: 2, x: 3}"])


def test_the_own_cross_view_must_start_before_the_end():
    """Issue 34: a warm-up as long as the run means the own cross view never runs."""
    with pytest.raises(ConfigError, match=r"losses.cross_view_warmup = 300: must be less than train.steps \(300\)"):
        load_config(preset="cpu", overrides=["train.steps=300"])
    assert load_config(preset="cpu", overrides=["train.steps=301"]).losses.cross_view_warmup == 300
    assert load_config(preset="paper", overrides=["losses.cross_view_warmup=10", "train.steps=5"])  # partner: unused
    for preset in ("paper", "paper_faithful", "cpu"):  # issue 30's limb terms: screened, in no preset yet
        c = load_config(preset=preset)
        assert (c.losses.coverage, c.losses.keypoint_coverage, c.losses.overlap, c.losses.rotation) == (0, 0, 0, 0)
        assert (c.losses.consensus_coverage, c.losses.separation, c.losses.relocation, c.model.recentre,
                c.model.deformation_warmup, c.model.rotation, c.model.axis_scales,
                c.model.local_rotation, c.model.root_part) == (0, 0, 0, False, 0, "camera", False, False,
                                                               False)  # issue 38's
    with pytest.raises(ConfigError, match="model.rotation: none does not run; set model.rotation=camera"):
        load_config(preset="cpu", overrides=["model.rotation=none", "model.local_rotation=true"])


def test_a_renamed_key_is_read_from_a_saved_config_and_named_in_a_new_one():
    """``model.predict_rotation`` became ``model.rotation`` (issue 38): what an earlier version saved (a run's
    config.yaml, a checkpoint, a model file) still reads, with the same meaning; a config written now is told the
    new key and its value."""
    saved = TrainConfig().to_dict()
    del saved["model"]["rotation"]
    for old, new in ((True, "camera"), (False, "none")):
        saved["model"]["predict_rotation"] = old
        assert TrainConfig.from_yaml(yaml.safe_dump(saved), "config.yaml").model.rotation == new
    for odd in ({"rotation": "world", "predict_rotation": True}, {"predict_rotation": 1}, {"predict_rotation": "yes"},
                {"predict_rotation": [True]}):  # both keys, or a value the table does not list: refused, named
        with pytest.raises(ConfigError, match="model.predict_rotation became model.rotation"):
            TrainConfig.from_yaml(yaml.safe_dump(saved | {"model": {**saved["model"], **odd}}), "config.yaml")
    del saved["model"]["predict_rotation"]
    assert TrainConfig.from_yaml(yaml.safe_dump(saved), "config.yaml") == TrainConfig()  # today's: untouched
    with pytest.raises(ConfigError, match=r"model.predict_rotation became model.rotation \(true → camera, "
                                          r"false → none\); remove model.predict_rotation and write "
                                          r"`model.rotation=VALUE` in its place"):
        load_config(preset="tiny", overrides=["model.predict_rotation=false"])


def test_a_resume_without_config_yaml_continues_with_the_checkpoints_config(tiny_config, tmp_path):
    """Issue 34 campaign: with RUN/config.yaml deleted, `cerberus train --out RUN --resume` fell back to the default
    preset (another dataset, another model) instead of the config the run's checkpoint holds."""
    from cerberus_core.train import train
    from cerberus_core.train.settings import resume_config

    config = tiny_config("train.steps=2", "train.progress=false")
    train(config, tmp_path / "run")
    (tmp_path / "run" / "config.yaml").unlink()
    resumed = resume_config(tmp_path / "run", ["train.steps=3"])
    assert resumed.data.root == config.data.root and resumed.train.steps == 3
    assert (resumed.model.num_parts, resumed.model.width) == (config.model.num_parts, config.model.width)
    assert resume_config(tmp_path / "empty") is None
