"""Networks on a stream dataset (issue 60, item 3): each model of ``--models`` trained on the
train split with each seed of ``--seeds``, scored on the test split on the sensor's clock
(docs/streams.md, "Networks on streams"): accuracy 0.5 to 100 ms after each stream's reference
time, the first answer's latency, the area under the accuracy-latency curve; a report with the
mean and a 95 % Student's t interval over seeds and the accuracy-latency picture.

    python benchmark/stream_bench.py DATASET --out DIR [--models cnn,mlp,gru_rotations]
        [--event-models snn_simlidar_tuned] [--window-models cnn] [--seeds 0,1,2,3,4] [--epochs N]
        [--validation 0.1] [--no-train] [--doc docs/streams.md]

A window model of ``--models`` (the registry's MLP, CNN, ...) is frame-based: trained on the
rotation windows, it answers at each frame's end. A stream network's recipe (a ``[stream]``
table: ``gru_rotations``, ``lif_stream``, or an outside one) reads whole streams, rotations or
binned events (:mod:`simlidar.bench.stream_sequences`). A spiking recipe of
``--event-models`` runs event-driven on arrival-coded windows. A window model of
``--window-models`` is frame-based but answers when its window is complete (the forward sector
published as soon as it is scanned), a cell of its own (``<model>-window``).

Cells are appended to DIR/cells.jsonl as they finish, and a run started again skips the
(model, seed) pairs already there (resumable); ``--no-train`` writes the report from them. A
recipe's noise augmentation is switched off (a stream carries no noise to draw anew).
"""

import argparse
import json
import sys
from pathlib import Path

from simlidar.bench.stream_bench import CELLS, ESTIMATE, plans, run_cells
from simlidar.bench.stream_report import report_table, summary, write_report
from simlidar.bench.stream_task import read_cells
from simlidar.errors import ConfigError
from simlidar.script_args import command_line, integers, numbers, run

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reproduction_table  # the split of a page around a generated block

DOC_START = "<!-- stream-results:start -->"
DOC_END = "<!-- stream-results:end -->"


def write_doc(path: Path, out: Path, cells: list[dict]) -> None:
    """Put the report's table into ``path`` between its lines DOC_START and DOC_END."""
    from simlidar.atomic import write_file

    before, _, after = reproduction_table.split(path.read_text(), path, DOC_START, DOC_END)
    estimate = json.loads((out / ESTIMATE).read_text()) if (out / ESTIMATE).exists() else None
    block = "\n".join(report_table(summary(cells), estimate))
    write_file(path, lambda temporary: temporary.write_text(before + block + after))
    print(f"{path}: wrote the results table")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--models",
        default="cnn,mlp",
        help="window models (frame-based: answers at frame ends) and stream networks (a recipe "
        "with a [stream] table)",
    )
    parser.add_argument(
        "--event-models",
        default="",
        help="spiking recipes run event-driven: "
        "arrival-coded windows, answers at the first output spike",
    )
    parser.add_argument(
        "--window-models",
        default="",
        help="window models answering when their window is complete (a sector clock), not at "
        "the frame's end",
    )
    parser.add_argument("--seeds", type=integers(0, 2**31), default=(0, 1, 2, 3, 4))
    parser.add_argument("--epochs", type=integers(1, 10_000, one=True), default=None)
    parser.add_argument("--validation", type=numbers(0, 0.5, one=True), default=0.1)
    parser.add_argument("--no-train", action="store_true")
    parser.add_argument(
        "--doc",
        type=reproduction_table.markdown_file,
        default=None,
        help=f"also put the report's table into FILE, between its lines {DOC_START} and "
        f"{DOC_END} (docs/streams.md)",
    )
    args = parser.parse_args(argv)
    if args.doc is not None:  # its markers, before anything is written
        reproduction_table.split(args.doc.read_text(), args.doc, DOC_START, DOC_END)
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: expected a folder")
    if args.no_train:
        cells = read_cells(args.out / CELLS, args.dataset.name)
        if not cells:
            raise ConfigError(
                f"--no-train: {args.out / CELLS}: no cells to report; expected a run's"
            )
    else:
        planned = plans(
            [m for m in args.models.split(",") if m],
            [m for m in args.event_models.split(",") if m],
            [m for m in args.window_models.split(",") if m],
        )
        cells = run_cells(
            args.dataset,
            args.out,
            planned,
            args.seeds,
            command_line("stream_bench.py", argv),
            epochs=lambda _: args.epochs,
            validation=args.validation,
            note=lambda line: print(line, flush=True),
        )
        if not cells:
            raise ConfigError("--models and --event-models: nothing to run; expected a model")
    write_report(args.out, cells)
    print(f"wrote {args.out / 'report.md'}")
    if args.doc is not None:
        write_doc(args.doc, args.out, cells)
    return 0


if __name__ == "__main__":
    run(main)
