"""Every numeric setting has a lower and an upper bound, declared once in the schema
(config/schema.py), and every numeric option of every command is held to one of those
declarations (cli/options.Bounded); the loader refuses values nested too deep
(docs/reliability.md section 10)."""
from dataclasses import fields

import click
import pytest

from tsel_data.config import load_config
from tsel_data.config.schema import SECTIONS, CommandOptions, Config, SplitConfig, declared
from tsel_data.errors import ConfigError

NUMERIC = ("int", "float", "Dist")


def _settings():
    """(key, field) of every setting of the schema: config keys and command options."""
    for f in fields(Config):
        if f.metadata:
            yield f.name, f
    for sec, cls in SECTIONS.items():
        for f in fields(cls):
            yield f"{sec}.{f.name}", f
    for f in fields(SplitConfig):
        yield f"splits.NAME.{f.name}", f
    for f in fields(CommandOptions):
        yield f.name, f


@pytest.mark.parametrize("key,f", [(k, f) for k, f in _settings() if str(f.type) in NUMERIC and not
                                   f.metadata.get("choices")], ids=lambda v: v if isinstance(v, str) else "")
def test_every_numeric_setting_is_bounded_below_and_above(key, f):
    m = f.metadata
    assert m.get("ge") is not None or m.get("gt") is not None, f"{key}: declare ge= or gt= in config/schema.py"
    assert m.get("le") is not None or m.get("lt") is not None, f"{key}: declare le= or lt= in config/schema.py"


def _commands(group, path=()):
    from tsel_data.cli import COMMANDS, cli

    ctx = click.Context(cli)
    for name in COMMANDS if group is None else group.list_commands(ctx):
        cmd = (cli if group is None else group).get_command(ctx, name)
        if isinstance(cmd, click.Group):
            yield from _commands(cmd, (*path, name))
        else:
            yield " ".join((*path, name)), cmd


def test_every_numeric_option_of_every_command_is_bounded_by_the_schema():
    from tsel_data.cli.options import Bounded

    seen, loose = 0, []
    for name, cmd in _commands(None):
        for p in cmd.params:
            if isinstance(p.type, Bounded):
                declared(p.type.key)  # a setting the schema declares
                seen += 1
            elif isinstance(p.type, (click.types.IntParamType, click.types.FloatParamType)):
                loose.append(f"tsel {name} {p.opts[0]}")
    assert not loose, f"numeric options without bounds (use cli.options.Bounded): {loose}"
    assert seen >= 15


@pytest.mark.parametrize("override,needle", [
    ("audio.target_level_dbfs=1000", "audio.target_level_dbfs must be >= -80 and <= 0 dBFS"),
    ("scene.speed=1e9", "scene.speed must be >= 0 and <= 360 deg/s"),
    ("scene.tir_db=1e6", "scene.tir_db must be >= -60 and <= 60 dB"),
    ('scene.tir_db=["uniform", -1e6, 0.0]', "scene.tir_db must be >= -60"),
    ("room.rt60=1e6", "room.rt60 must be > 0 and <= 20 s"),
    ("noise.babble=65", "noise.babble must be >= 0 and <= 64"),
    ("output.shard_size=1e9", "output.shard_size must be >= 1 and <= 100000"),
    ('noise.sensor="dbfs"\nnoise.sensor_level=100', "noise.sensor_level up to 100 dBFS would bury the target"),
    ("array.capsules=" + "[" * 5000 + "]" * 5000, "nested 5000 levels deep"),
    ("array.capsules=" + "[" * 40 + "]" * 40, "nested 40 levels deep"),
])
def test_values_that_crashed_are_refused_by_their_bound(override, needle):
    with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        load_config(preset="demo", overrides=override.split("\n"))


def test_a_deeply_nested_toml_file_is_a_config_error(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("[array]\ncapsules = " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError, match="deep.toml: values nested 5000 levels deep"):
        load_config(path=str(path))
