"""``tsel corpus``: the built-in demo corpus."""
import click


@click.group()
def corpus():
    """Captioned clip corpora."""


@corpus.command("synth")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Folder to write into.")
@click.option("--seed", default=0, show_default=True, help="Corpus seed (same seed, same bytes).")
@click.option("--clips-per-type", default="4,1,1", show_default=True, metavar="TRAIN,VAL,TEST",
              help="Clips of each sound type in each split.")
def synth(out_dir, seed, clips_per_type):
    """Synthesise the demo corpus: WAVs plus AudioCaps-format train/val/test CSVs."""
    from ..demo import synth_corpus
    from ..errors import TselError

    try:
        counts = tuple(int(x) for x in clips_per_type.split(","))
    except ValueError:
        raise TselError(f"--clips-per-type {clips_per_type!r}: expected three integers, e.g. 4,1,1") from None
    info = synth_corpus(out_dir, seed=seed, clips_per_type=counts)
    click.echo(f"demo corpus in {out_dir}: {len(info['types'])} sound types, "
               + ", ".join(f"{k} {v} clips" for k, v in info["clips"].items())
               + f", {info['bytes'] / 1e6:.0f} MB")
