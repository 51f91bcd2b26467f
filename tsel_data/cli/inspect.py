"""``tsel inspect DIR SCENE``: describe one scene; optionally draw it and write its audio."""
import click

from .options import force_option, note_unfinished, roots_options


@click.command("inspect")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.argument("scene")
@click.option("--split", help="Look the scene id up in this split only.")
@click.option("--png", type=click.Path(dir_okay=False), help="Draw room, azimuth and elevation, activity and "
              "spectrogram here.")
@click.option("--wav", type=click.Path(dir_okay=False), help="Write the mixture here (float32 WAV, all channels), "
              "with a headphone preview (X.stereo.wav) and each source alone (X.target.stereo.wav, "
              "X.interferer1.stereo.wav, ...).")
@click.option("--no-stems", is_flag=True, help="With --wav: not the per-source stems (they are rendered again from "
              "the recipe, which needs the clips).")
@click.option("--receiver", help="A dataset heard by several receivers: this one's audio (default the first).")
@roots_options
@force_option
def inspect_cmd(dataset_dir, scene, split, png, wav, no_stems, receiver, corpus_dir, bank, force):
    """Show SCENE of DATASET_DIR: a scene id (test-000003) or SPLIT/INDEX (test/3)."""
    from ..errors import TselError
    from ..inspect import find_scene, inspect_outputs, inspect_scene, stereo_path  # h5py, matplotlib: only here
    from ..store.outputs import claim_outputs

    note_unfinished(dataset_dir)
    found = find_scene(dataset_dir, scene, split, receiver)
    outputs = inspect_outputs(png, wav)
    stems = wav and not no_stems
    if stems:
        from ..stems import stem_paths, write_stems  # rendering: scipy and the simulators load only here

        outputs += stem_paths(wav, len(found.record.sources), bool(found.record.noise))
    with claim_outputs(outputs, force, "tsel inspect"):
        _, text = inspect_scene(dataset_dir, found, png=png, wav=wav)
        click.echo(text)
        if png:
            click.echo(f"picture: {png}")
        if wav:
            click.echo(f"audio: {wav} (all channels), {stereo_path(wav)} (headphones)")
        if stems:
            try:
                paths, same = write_stems(dataset_dir, found, wav, corpus_dir, bank)
            except TselError as e:
                click.echo(f"note: no stems: {e}", err=True)
            else:
                click.echo("stems: " + ", ".join(paths))
                if not same:
                    click.echo("note: the stems do not add up to the stored mixture: the clips or the RIR bank "
                               "changed since the dataset was made", err=True)
