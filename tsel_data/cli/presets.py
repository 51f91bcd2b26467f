"""``tsel presets``: list presets, or print one fully resolved as TOML."""
import click


@click.command("presets")
@click.argument("name", required=False)
def presets_cmd(name):
    """List the built-in presets, or print NAME as a complete TOML config to start from."""
    from ..config import load_config, preset_names, to_toml

    if not name:
        for p in preset_names():
            click.echo(p)
        return
    click.echo(to_toml(load_config(preset=name)), nl=False)
