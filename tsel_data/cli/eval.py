"""``tsel eval --pred FILE DIR --split test``: the paper's azimuth error of a model's predictions."""
import json

import click


@click.command("eval")
@click.argument("dataset_dir", type=click.Path(file_okay=False))
@click.option("--pred", "pred_file", required=True, type=click.Path(),
              help="Predictions, JSON Lines: one {\"scene_id\", \"azimuth\" | \"distribution\"} per scene.")
@click.option("--split", default="test", show_default=True, help="Split the predictions are for.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON (with per-scene errors) instead of text.")
@click.option("--dcase", is_flag=True,
              help="The DCASE 2024 SELD metrics instead: --pred is a folder of DCASE output CSVs, one per scene "
                   "(fold{n}_{scene_id}.csv as tsel export dcase names them).")
def eval_cmd(dataset_dir, pred_file, split, as_json, dcase):
    """Mean absolute azimuth error (deg, wrap-around) of the target, and accuracy within 5/10/20 deg; or, with
    --dcase, the DCASE SELD metrics (F, error rate, localisation error and recall, distance errors)."""
    if dcase:
        from ..tools.evaluate_dcase import evaluate_dcase
        from ..export.dcase import CLASSES

        scores = evaluate_dcase(dataset_dir, split, pred_file)
        click.echo(json.dumps(scores.to_dict(), indent=1) if as_json else
                   f"split {split}: " + scores.format_text(CLASSES))
        return
    from ..tools.evaluate import evaluate

    result = evaluate(dataset_dir, split, pred_file)
    click.echo(json.dumps(result.to_dict(), indent=1) if as_json else result.format_text())
