"""``tsel inspect DIR SCENE``: describe one scene; optionally draw it and write its audio.
``tsel inspect DIR --sheet F.html``: many scenes at a glance, with players."""
import click

from .options import Bounded, force_option, note_unfinished, roots_options


@click.command("inspect")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.argument("scene", required=False)
@click.option("--split", help="Look the scene id up in this split only (with --sheet: take the scenes from it).")
@click.option("--png", type=click.Path(dir_okay=False), help="Draw the query, noise, room, array frame, "
              "azimuth and elevation, activity and spectrogram here.")
@click.option("--wav", type=click.Path(dir_okay=False), help="Write the mixture here (float32 WAV, all channels), "
              "with a headphone preview (X.stereo.wav) and each source alone (X.target.stereo.wav, "
              "X.interferer1.stereo.wav, ...).")
@click.option("--no-stems", is_flag=True, help="With --wav: not the per-source stems (they are rendered again from "
              "the recipe, which needs the clips).")
@click.option("--sheet", type=click.Path(dir_okay=False), help="Instead of one SCENE, a contact sheet of --scenes "
              "scenes: F.html (picture, query, captions, labels in words and a player per scene; its files in "
              "F_files/) or F.png (the pictures alone).")
@click.option("--scenes", "n_scenes", type=Bounded("scenes", int), default=24, show_default=True,
              help="With --sheet: how many scenes, spread evenly over the split(s).")
@click.option("--receiver", help="A dataset heard by several receivers: this one's audio (default the first).")
@roots_options
@force_option
def inspect_cmd(dataset_dir, scene, split, png, wav, no_stems, sheet, n_scenes, receiver, corpus_dir, bank, force):
    """Show SCENE of DATASET_DIR: a scene id (test-000003) or SPLIT/INDEX (test/3); or, with
    --sheet, many scenes at once."""
    if sheet:
        if scene or png or wav:
            raise click.UsageError("--sheet shows many scenes: give it without SCENE, --png or --wav")
        return _sheet(dataset_dir, sheet, n_scenes, split, receiver, force)
    if not scene:
        raise click.UsageError("missing SCENE (a scene id such as test-000000, or SPLIT/INDEX such as test/0), or "
                               "--sheet FILE for many scenes")
    from ..errors import TselError
    from ..tools.inspect import find_scene, inspect_outputs, inspect_scene, stereo_path  # h5py, matplotlib: only here
    from ..store.outputs import claim_outputs

    note_unfinished(dataset_dir)
    found = find_scene(dataset_dir, scene, split, receiver)
    outputs = inspect_outputs(png, wav)
    recorded = found.record is not None and found.record.recorded
    stems = wav and not no_stems and not recorded  # a recording's sources were recorded together
    if stems:
        from ..job.stems import stem_paths, write_stems  # rendering: scipy and the simulators load only here

        outputs += stem_paths(wav, len(found.record.sources), bool(found.record.noise))
    with claim_outputs(outputs, force, "tsel inspect"):
        _, text = inspect_scene(dataset_dir, found, png=png, wav=wav)
        click.echo(text)
        if png:
            click.echo(f"picture: {png}")
        if wav:
            click.echo(f"audio: {wav} (all channels), {stereo_path(wav)} (headphones)")
        if wav and recorded and not no_stems:
            click.echo("note: no stems: the sources of a recorded scene were recorded together", err=True)
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


def _sheet(dataset_dir, path, n_scenes, split, receiver, force):
    from ..tools.sheet import chosen_scenes, files_dir, is_picture_sheet, scene_ids, sheet_outputs, write_sheet
    from ..store.outputs import claim_outputs

    note_unfinished(dataset_dir)
    chosen = chosen_scenes(dataset_dir, n_scenes, split, receiver)
    with claim_outputs(sheet_outputs(path, scene_ids(dataset_dir, chosen, receiver)), force, "tsel inspect"):
        n = write_sheet(dataset_dir, path, chosen, receiver)
    splits = ", ".join(dict.fromkeys(sp for sp, _ in chosen))
    extra = "" if is_picture_sheet(path) else f"; pictures and previews in {files_dir(path)}/"
    click.echo(f"sheet: {path} ({n} scenes of {splits}{extra})")
