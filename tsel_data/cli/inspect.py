"""``tsel inspect DIR SCENE``: describe one scene; optionally draw it and write its audio."""
import click


@click.command("inspect")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.argument("scene")
@click.option("--split", help="Look the scene id up in this split only.")
@click.option("--png", type=click.Path(dir_okay=False), help="Draw room, azimuth tracks and spectrogram here.")
@click.option("--wav", type=click.Path(dir_okay=False), help="Write the mixture here (float32 WAV, all channels).")
def inspect_cmd(dataset_dir, scene, split, png, wav):
    """Show SCENE of DATASET_DIR: a scene id (test-000003) or SPLIT/INDEX (test/3)."""
    from ..inspect import inspect_scene

    _, text = inspect_scene(dataset_dir, scene, split=split, png=png, wav=wav)
    click.echo(text)
    for what, path in (("picture", png), ("audio", wav)):
        if path:
            click.echo(f"{what}: {path}")
