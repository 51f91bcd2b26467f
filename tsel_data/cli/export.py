"""``tsel export FORMAT DIR --out DIR2``: the dataset in other tools' formats.

One command per writer of :data:`tsel_data.export.WRITERS`, its options read from the
writer's declaration: a new format needs nothing here. The registry (and h5py with it)
is imported only when an export command runs, not for ``tsel --help``.
"""
from __future__ import annotations

import click

from .options import Bounded


class _ExportGroup(click.Group):
    """The export formats, looked up in the registry when asked for."""

    def list_commands(self, ctx):
        from ..export import WRITERS

        return list(WRITERS)

    def get_command(self, ctx, name):
        from ..export import WRITERS

        writer = WRITERS.get(name)
        return None if writer is None else _command(writer)


@click.group("export", cls=_ExportGroup)
def export_cmd():
    """Export a dataset for other tools (dcase, webdataset, hf, lhotse, recipes, captions, qa, card)."""


def _option(o):
    flag = "--" + o.name.replace("_", "-")
    if o.flag:
        return click.option(f"{flag}/--no-{o.name.replace('_', '-')}", o.name, default=bool(o.default),
                            show_default=True, help=o.help)
    kind = click.Choice(list(o.choices)) if o.choices else Bounded(o.bound, int, o.parse) if o.bound else None
    return click.option(flag, o.name, default=o.default, type=kind, show_default=o.default is not None, help=o.help)


def _command(writer):
    def run(dataset_dir, out_dir, splits, force, quiet, **options):
        from ..export import run_export

        w = writer(**options)
        result = run_export(w, dataset_dir, out_dir, splits or None, force=force, progress=False if quiet else None)
        for line in w.lines(result):
            click.echo(line)

    for o in reversed((*writer.options, *writer.COMMON)):
        run = _option(o)(run)
    run = click.option("--quiet", is_flag=True, help="No progress bar (it shows only on a terminal anyway).")(run)
    run = click.option("--force", is_flag=True, help="Replace an export of something else in --out, or write over "
                       "files no export wrote.")(run)
    run = click.option("--split", "splits", multiple=True, help="Only this split (repeatable; default: all).")(run)
    run = click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False),
                       help="Output folder (the export's own).")(run)
    run = click.argument("dataset_dir", type=click.Path(file_okay=False))(run)
    return click.command(writer.name, help=writer.summary)(run)
