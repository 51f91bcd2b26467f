"""``tsel export dcase DIR --out DIR2``: the dataset in other tools' formats."""
import click

from ..choices import WavSubtype, values


@click.group("export")
def export_cmd():
    """Export a dataset for other tools."""


@export_cmd.command("dcase")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Output folder.")
@click.option("--split", "splits", multiple=True, help="Only this split (repeatable; default: all).")
@click.option("--subtype", type=click.Choice(values(WavSubtype)), default="PCM_16", show_default=True,
              help="WAV sample format (the DCASE baselines expect 16-bit).")
@click.option("--quiet", is_flag=True, help="No progress bar (it shows only on a terminal anyway).")
def dcase_cmd(dataset_dir, out_dir, splits, subtype, quiet):
    """DCASE 2024 Task 3 layout: WAV per scene, frame/class/source/azimuth/elevation/distance CSVs, queries."""
    from ..export import export_dcase

    summary = export_dcase(dataset_dir, out_dir, splits or None, subtype=subtype, progress=False if quiet else None)
    for split, v in summary["splits"].items():
        click.echo(f"{split}: fold {v['fold']}, {v['scenes']} scenes, {v['rows']} label rows -> {v['audio_dir']}")
    click.echo(f"queries: {out_dir}/queries.csv; classes: 0 = target, 1 = interferer ({out_dir}/classes.json)")
