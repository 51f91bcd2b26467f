"""``tsel stats DIR``: per-split statistics of a dataset (text, JSON, plots)."""
import json

import click

from .options import force_option, note_unfinished


@click.command("stats")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.option("--split", "splits", multiple=True, help="Only this split (repeatable; default: all).")
@click.option("--png", type=click.Path(dir_okay=False), help="Also draw histograms to this PNG file.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
@force_option
def stats_cmd(dataset_dir, splits, png, as_json, force):
    """Scenes, clip reuse, target azimuths, separation, distances, rooms, RT60, levels, queries."""
    from ..tools.stats import dataset_stats, format_text, plot_stats
    from ..store.outputs import claim_outputs

    note_unfinished(dataset_dir)
    with claim_outputs([png], force, "tsel stats"):  # refused before the statistics are read, not after
        st = dataset_stats(dataset_dir, splits or None)
        if as_json:
            click.echo(json.dumps({k: {kk: vv for kk, vv in v.items() if kk != "raw"} for k, v in st.items()},
                                  indent=1))
        else:
            click.echo(format_text(st))
        if png:
            plot_stats(st, png)
            if not as_json:
                click.echo(f"plots: {png}")
