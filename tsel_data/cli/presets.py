"""``tsel presets``: list presets, or print one fully resolved as commented TOML."""
import click


@click.command("presets")
@click.argument("name", required=False)
@click.option("--receivers", "receivers", is_flag=True, help="List the receivers scene.format can name instead.")
def presets_cmd(name, receivers):
    """List the built-in presets with what each is for and what it needs, or print NAME as
    a complete TOML config to start from (its description, what it needs, then every key
    with its help and unit as comments)."""
    from ..config import load_config, preset_names, preset_text, to_toml

    if receivers:
        from ..receivers import RECEIVERS

        for spec in RECEIVERS.values():
            n = "config" if spec.configured else str(len(spec.layout(_SIDED)))
            click.echo(f"{spec.name:<13}{n:>6} ch  {spec.summary}")
        return
    if not name:
        for p in preset_names():
            text = " ".join(_description(preset_text(p)).split())
            needs = [n.split(" ", 1)[0] for n in preset_needs(load_config(preset=p, validate=False))]
            click.echo(f"{p:<22}{text.split(': ')[0].split('. ')[0].rstrip('.')}"
                       + (f" (needs {', '.join(needs)})" if needs else ""))
        return
    cfg = load_config(preset=name, validate=False)  # a preset may need --bank or --corpus-dir to be complete
    needs = preset_needs(cfg)
    header = _description(preset_text(name))
    if needs:
        header += "\n\nWhat it needs on the command line:\n" + "\n".join(f"  {n}" for n in needs)
    click.echo(to_toml(cfg, comments=True, header=header), nl=False)


class _Sided:
    """A pose for counting a receiver's channels: mic4's count does not depend on its side."""

    side = 0.11


_SIDED = _Sided()


def preset_needs(cfg) -> list[str]:
    """What a preset leaves for the command line: one line per option, ``--corpus-dir
    DIR: ...`` when it names no corpus, ``--bank PATH: ...`` when its splits name bank
    rooms but it names no bank."""
    out = []
    if not cfg.corpus.dir:
        manifests = ", ".join(dict.fromkeys(sp.manifest for sp in cfg.splits.values() if sp.count))
        out.append(f"--corpus-dir DIR: your corpus, the folder with {manifests} ({cfg.corpus.format} manifests, see "
                   f"manifests/README.md) and their audio")
    rooms = {n: sp.rooms for n, sp in cfg.splits.items() if sp.rooms and sp.count}
    if rooms and not cfg.room.bank:
        named = "; ".join(f"{n} {', '.join(map(str, r))}" for n, r in rooms.items())
        out.append(f"--bank PATH: an RIR bank in {cfg.scene.format} with the rooms the splits name ({named}); see "
                   f"rir_banks/README.md")
    return out


def _description(text: str) -> str:
    """The comment lines a preset file starts with."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return "\n".join(lines)
