"""Dataset configuration: the schema (schema.py), its rules (rules.py), loading presets,
files and overrides (load.py), writing TOML (toml.py) and the key tables of
docs/config.md (doc.py).

Import order: ``schema`` -> ``receiver`` (the config's receiver as an ArrayPose) ->
``rules`` -> ``load`` -> ``compare`` (which keys two configs
set differently); ``toml`` and ``doc`` use the schema.
"""
from .compare import Difference, config_differences
from .load import load_config, parse_config, preset_names, preset_text
from .rules import (MAX_NUMBER, check_raw_config, config_problems, geometry_problems, rooms_without_bank,
                    validate_config)
from .schema import (SECTIONS, TOP_KEYS, ArrayConfig, AudioConfig, Config, CorpusConfig, OutputConfig, RoomConfig,
                     SceneConfig, SourcesConfig, SplitConfig)
from .toml import to_toml

__all__ = [
    "MAX_NUMBER", "SECTIONS", "TOP_KEYS", "ArrayConfig", "AudioConfig", "Config", "CorpusConfig", "Difference",
    "OutputConfig", "RoomConfig", "SceneConfig", "SourcesConfig", "SplitConfig", "check_raw_config",
    "config_differences", "config_problems",
    "geometry_problems", "load_config", "parse_config", "preset_names", "preset_text", "rooms_without_bank",
    "to_toml", "validate_config",
]
