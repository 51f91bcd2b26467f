"""``tsel check``: validate a config and its inputs, or verify a written dataset."""
from __future__ import annotations

import json

import click

from ..errors import TselError
from . import say
from .options import RUN_ONLY, Bounded, config_options, load, manifest_option, run_only_options, worker_count

SHOW = 20  # problems printed per kind; the rest are counted (--json lists them all)


@click.command("check")
@click.argument("dataset_dir", required=False, type=click.Path(file_okay=False))
@config_options
@click.option("--out", "out_dir", type=click.Path(file_okay=False),
              help="With a config: the output folder a run would use (checked for space, writability, an old plan).")
@click.option("--workers", type=Bounded("workers", int), default=0, help="Processes (default: number of cores).")
@click.option("--no-plan", is_flag=True, help="With a config: skip sampling every scene in memory (with corpus.check = \"drawn\" every clip is then checked in full: no plan says which it draws).")
@click.option("--no-audio", is_flag=True, help="With DIR: skip checking every audio sample is finite.")
@click.option("--json", "as_json", is_flag=True, help="Print the full report as JSON.")
@click.option("--release", "release_dir", type=click.Path(file_okay=False),
              help="With DIR: hold it against this recipe release, scene by scene (audio, labels, record).")
@manifest_option
@run_only_options
def check_cmd(dataset_dir, out_dir, workers, no_plan, no_audio, as_json, release_dir, **opts):
    """Check a config and everything it reads before rendering (`tsel check --preset/--config ...`),
    or verify a finished dataset (`tsel check DIR`: shards, sha256, HDF5 vs JSON, counts).

    Exits 0 when nothing stops a run (warnings, e.g. skipped bad clips, are printed),
    2 when something does; every problem is one line naming the file and row.
    """
    from ..job.preflight import check_config
    from ..store.check import check_dataset

    run = {k: opts.pop(k) for k in RUN_ONLY}
    config_opts = opts
    release = release_dir
    if not dataset_dir and run["release"]:
        raise TselError("--from rebuilds a release, which `tsel check` does not: check the rebuilt dataset with "
                        "`tsel check DIR --release REL`")
    steering = [f"--{k.replace('_', '-')}" for k in RUN_ONLY if k not in ("release", "quiet") and run[k]]
    if steering:
        click.echo(f"note: {', '.join(steering)} steer(s) a run, not what it makes: checked as without", err=True)

    if dataset_dir and (config_opts.get("preset") or config_opts.get("config_path") or config_opts.get("manifest")):
        raise TselError("give either a dataset folder or --preset/--config, not both")
    if release and not dataset_dir:
        raise TselError("--release holds a dataset against a release: give the dataset folder, `tsel check DIR "
                        "--release REL`")
    summarise = None
    if release:
        from ..store.release import check_against_release, release_summary_lines

        rep, summarise = check_against_release(dataset_dir, release), release_summary_lines
    elif dataset_dir:
        rep = check_dataset(dataset_dir, workers=worker_count(workers), audio=not no_audio)
    else:
        cfg = load(**config_opts, validate=False)  # as `tsel generate`, but every problem is collected
        rep = check_config(cfg, out_dir=out_dir, workers=worker_count(workers), plan=not no_plan)
    if as_json:
        click.echo(json.dumps(rep.to_dict(), indent=1, ensure_ascii=False))
    else:
        for line in (summarise or type(rep).summary_lines)(rep):
            click.echo(line)
        _print("warning", rep.warnings)
        _print("error", rep.messages())
    if not rep.ok:
        click.get_current_context().exit(2)


def _print(kind: str, lines: list[str]) -> None:
    for line in lines[:SHOW]:
        click.echo(f"{kind}: {say(line)}", err=True)
    if len(lines) > SHOW:
        click.echo(f"{kind}: ... and {len(lines) - SHOW:,} more (--json lists all)", err=True)
