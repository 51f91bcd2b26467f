"""``tsel corpus``: the built-in demo corpus."""
import click


@click.group()
def corpus():
    """Captioned clip corpora."""


@corpus.command("synth")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Folder to write into.")
@click.option("--seed", default=0, show_default=True, help="Corpus seed (same seed, same bytes).")
def synth(out_dir, seed):
    """Synthesise the demo corpus: WAVs plus AudioCaps-format train/val/test CSVs."""
    from ..demo import synth_corpus

    info = synth_corpus(out_dir, seed=seed)
    click.echo(f"demo corpus in {out_dir}: " + ", ".join(f"{k}={v}" for k, v in info.get("counts", {}).items()))
