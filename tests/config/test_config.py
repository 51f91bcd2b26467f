import pytest

from tsel_data.config import load_config, parse_config, preset_names
from tsel_data.scene.distributions import Dist
from tsel_data.errors import ConfigError


def test_presets_load():
    names = preset_names()
    for p in ("demo", "paper-sim-2dir", "paper-sim-1dir-1add", "realistic-sim"):
        assert p in names
        load_config(preset=p)
    paper = load_config(preset="paper-sim-2dir")
    assert {k: v.count for k, v in paper.splits.items()} == {"train": 7224, "val": 903, "test": 903}
    assert paper.room.height.bounds == (5.0, 15.0) and paper.room.rt60.bounds == (0.5, 1.0)
    assert paper.array.side.bounds == (0.10, 0.13) and paper.array.height.bounds == (1.0, 1.2)
    assert load_config(preset="paper-sim-1dir-1add").scene.scenario.options == ("directional+additive",)
    assert load_config(preset="realistic-sim").room.height.bounds == (2.5, 4.0)


def test_unknown_key_suggests_closest():
    with pytest.raises(ConfigError, match=r"unknown config key room.'rt6'.*did you mean room.rt60"):
        parse_config({"room": {"rt6": 0.5}})
    with pytest.raises(ConfigError, match="did you mean sources"):
        parse_config({"source": {}})


def test_overrides_and_flags():
    c = load_config(preset="demo", overrides=['room.rt60=["uniform", 0.2, 0.4]', "scene.min_separation=30",
                                              "room.rir_method=ism"], seed=7, splits={"train": 5})
    assert c.room.rt60 == Dist("uniform", (0.2, 0.4))
    assert c.scene.min_separation == 30.0 and c.room.rir_method == "ism"
    assert c.seed == 7 and c.splits["train"].count == 5


@pytest.mark.parametrize("override,message", [
    ('room.rt60=["uniform", 1.0, 0.5]', "min 1.0 > max 0.5"),
    ("room.rir_method=magic", "rir_method = 'magic' is not one of"),
    ('scene.scenario="three-directional"', "three-directional"),
    ("sources.distance=40.0", "cannot fit in the largest room"),
    ("scene.min_separation=200", "impossible"),
    ("array.wall_margin=9.0", "twice the wall margin"),
    ('room.length=["gauss", 1, 2]', "not a distribution"),
    ("seed=-1", "seed"),
    ("audio.label_hop=0.3", "whole number of label_hop"),
    ("scene.interferers=0", "at least two sources"),
])
def test_impossible_configs_are_rejected(override, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace("[", r"\[")):
        load_config(preset="demo", overrides=[override])


def test_bad_toml_file(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text("[room\nrt60 = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(path=str(p))
    with pytest.raises(ConfigError, match="not found"):
        load_config(path=str(tmp_path / "missing.toml"))


def test_config_dict_round_trip():
    c = load_config(preset="demo")
    assert parse_config(c.to_dict()) == c


def test_distribution_sampling_is_reproducible_and_in_range():
    import numpy as np

    d = Dist.parse(["uniform", 2.0, 3.0], "x")
    a = [d.sample(np.random.default_rng(1)) for _ in range(3)]
    assert a[0] == a[1] == a[2] and 2.0 <= a[0] <= 3.0
    c = Dist.parse(["choose", ["a", "b"], [0.0, 1.0]], "x")
    assert {c.sample(np.random.default_rng(i)) for i in range(20)} == {"b"}
    t = Dist.parse(["truncnorm", 0.0, 10.0, -1.0, 1.0], "x")
    assert all(-1 <= t.sample(np.random.default_rng(i)) <= 1 for i in range(50))


def test_presets_print_as_toml_that_loads_back(tmp_path):
    from tsel_data.config import to_toml

    for name in preset_names():
        c = load_config(preset=name)
        p = tmp_path / f"{name}.toml"
        p.write_text(to_toml(c))
        assert load_config(path=str(p)) == c


def test_relative_paths_in_a_config_file_resolve_against_its_folder(tmp_path):
    (tmp_path / "sub").mkdir()
    p = tmp_path / "sub" / "c.toml"
    p.write_text('[corpus]\ndir = "../corpus"\n')
    assert load_config(path=str(p)).corpus.dir == str(tmp_path / "sub" / "../corpus")
