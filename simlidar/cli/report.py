"""``simlidar report``: the finished cells of several benchmark runs in one report."""

from pathlib import Path

import click

from simlidar.cli.options import OutFolder, need_torch


@click.command()
@click.argument("folders", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=OutFolder(),
    default=Path("bench/report"),
    show_default=True,
    help="Folder for the merged report: new, empty, or an earlier report of this command.",
)
def report(folders, out):
    """Merge the finished cells of benchmark output folders (written by simlidar bench: yours
    and the committed benchmark/results/paper, say) into one report beside the paper's
    numbers: results.json, report.md and pictures in --out. Refused before anything is
    written: a cell that does not follow the published cell schema, cells of one dataset
    name made from different data, two different cells of the same dataset, model and
    seed."""
    need_torch("report")
    from simlidar.bench.merge import merge_report

    results, notes = merge_report(list(folders), out)
    runs = len(results["merged_from"])
    click.echo(
        f"{len(results['cells'])} cells of {runs} run{'' if runs == 1 else 's'} in {out}: "
        "results.json, report.md"
    )
    for source in results["merged_from"]:
        click.echo(f"  {source['folder']}: {source['cells']} cells")
    for note in notes:
        click.echo(f"  {note}")
