"""``tsel presets``: list presets, or print one fully resolved as commented TOML."""
import click


@click.command("presets")
@click.argument("name", required=False)
def presets_cmd(name):
    """List the built-in presets with what each is for, or print NAME as a complete TOML
    config to start from (every key, with its help and unit as comments)."""
    from ..config import load_config, preset_names, preset_text, to_toml

    if not name:
        for p in preset_names():
            text = " ".join(_description(preset_text(p)).split())
            click.echo(f"{p:<22}{text.split(': ')[0].split('. ')[0].rstrip('.')}")
        return
    cfg = load_config(preset=name, validate=False)  # a preset may need --bank or --corpus-dir to be complete
    click.echo(to_toml(cfg, comments=True, header=_description(preset_text(name))), nl=False)


def _description(text: str) -> str:
    """The comment lines a preset file starts with."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return "\n".join(lines)
