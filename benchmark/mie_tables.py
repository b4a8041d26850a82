"""The Mie tables of water that fog and rain read (issue 62, item 5): Q_ext and Q_back of
water spheres, each a mean over a cell of size parameters, for visible light (550 nm, where
visibility is defined) and the near infrared of 903-905 nm LiDARs.

    python benchmark/mie_tables.py            # write sensors/atmosphere/water-mie-*.json
    python benchmark/mie_tables.py --check    # compute them again and compare

Water's refractive index in each band is ``sensors/atmosphere/water.toml``'s (with its
source). The size parameter x = pi D / lambda from ``X_LOW`` to ``X_HIGH`` (fog drops of 0.1
um to rain drops of 6 mm at 903 nm) is cut into ``PER_DECADE`` cells a decade of equal log
width; each cell's value is the mean over ``SAMPLES`` sizes, one in each of as many equal
slices of the cell, at a place drawn by ``numpy.random.default_rng(0)``
(:func:`simlidar.sensor.scattering.cell_means`). Large drops' backscatter rings far faster
with x than a cell is wide, so a cell mean carries sampling noise: the script prints the
standard error of the cells' Q_back means, estimated from their samples' spread. The series
themselves (:mod:`simlidar.sensor.mie`) are checked against published tables in
tests/sensor/test_mie.py. ``--check`` computes every cell again and fails unless each equals
the committed file's within a relative 1e-9 (the same code, another machine's floating point).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from simlidar.errors import ResultsError
from simlidar.script_args import run
from simlidar.sensor.scattering import (
    MieTable,
    cell_means,
    checked_table,
    load_atmosphere,
    table_path,
    table_to_dict,
)

X_LOW, X_HIGH = 0.1, 22000.0
PER_DECADE = 40
SAMPLES = 128


def edges() -> np.ndarray:
    decades = np.log10(X_HIGH / X_LOW)
    cells = int(np.ceil(decades * PER_DECADE))
    return np.geomspace(X_LOW, X_HIGH, cells + 1)


def make(band: str) -> MieTable:
    """The table of ``band``, with each cell's standard error of its Q_back mean."""
    index = load_atmosphere().index[band]
    cut = edges()
    return MieTable(band, index, cut, *cell_means(index, cut, SAMPLES))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--check", action="store_true", help="compute the tables again and compare, writing nothing"
    )
    args = parser.parse_args(argv)
    for band in ("visible", "nir"):
        table = make(band)
        path = table_path(band)
        relative = table.q_back_error / table.q_back
        for low, high in ((X_LOW, 10.0), (10.0, 1000.0), (1000.0, X_HIGH)):
            inside = (table.edges[:-1] >= low) & (table.edges[:-1] < high)
            print(
                f"{band}, x {low:g} to {high:g}: Q_back cell means' standard error "
                f"median {100 * np.median(relative[inside]):.1f} %, "
                f"largest {100 * relative[inside].max():.1f} %"
            )
        if args.check:
            kept = checked_table(str(path), json.loads(path.read_text()))
            for key in ("edges", "q_ext", "q_back", "q_back_error"):
                ours, theirs = getattr(table, key), getattr(kept, key)
                if len(ours) != len(theirs) or not np.allclose(ours, theirs, rtol=1e-9, atol=0):
                    raise ResultsError(f"{path}: {key} differs from the computed table")
            print(f"{path}: the same within 1e-9")
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        made_by = "python benchmark/mie_tables.py"
        path.write_text(json.dumps(table_to_dict(table, made_by)) + "\n")
        print(f"{path}: {len(table.q_ext)} cells, x {X_LOW:g} to {X_HIGH:g}, m = {table.index}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    run(main)
