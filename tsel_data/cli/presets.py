"""``tsel presets``: list presets, or print one resolved as TOML-like text."""
import json

import click


@click.command("presets")
@click.argument("name", required=False)
def presets_cmd(name):
    """List the built-in presets, or show NAME fully resolved (every default filled in)."""
    from ..config import load_config, preset_names

    if not name:
        for p in preset_names():
            click.echo(p)
        return
    click.echo(json.dumps(load_config(preset=name).to_dict(), indent=2))
