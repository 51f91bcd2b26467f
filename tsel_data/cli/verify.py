"""``tsel verify DIR``: check labels against the audio with a classical localizer."""
import json

import click

from .options import Bounded, note_unfinished


@click.command("verify")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.option("--split", "splits", multiple=True, help="Only this split (repeatable; default: all).")
@click.option("--tolerance", type=Bounded("tolerance"), default=20.0, show_default=True, help="Agreement threshold (deg).")
@click.option("--max-scenes", type=Bounded("max_scenes", int), help="Check only the first N scenes of each split.")
@click.option("--fail-under", type=Bounded("fail_under"), default=0.0, show_default=True,
              help="Exit with 1 if a split's agreement rate (0-1) is below this.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON (every disagreeing scene, every source).")
@click.option("--quiet", is_flag=True, help="No progress bar (it shows only on a terminal anyway).")
@click.option("--receiver", help="A dataset heard by several receivers: judge this one's audio (default the first).")
@click.pass_context
def verify_cmd(ctx, dataset_dir, splits, tolerance, max_scenes, fail_under, as_json, quiet, receiver):
    """Agreement of labels with a classical localizer (SRP-PHAT for arrays, the intensity vector for FOA, level
    differences for the DCASE stereo pair), per split."""
    from ..tools.verify import verify_dataset

    note_unfinished(dataset_dir)
    report = verify_dataset(dataset_dir, splits or None, tolerance=tolerance, max_scenes=max_scenes,
                            progress=False if quiet else None, receiver=receiver)
    click.echo(json.dumps(report.to_dict(), indent=1) if as_json else report.format_text())
    low = [s for s, v in report.splits.items() if v["tested"] and v["rate"] < fail_under]
    if low:
        click.echo(f"agreement below {fail_under:g} in split(s): {', '.join(low)}", err=True)
        ctx.exit(1)
