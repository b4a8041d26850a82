"""Small inputs of the converters that tests write themselves, shared by the converter tests
and the sources' conformance test (tests/test_sources.py): DVS barrel MATLAB files in the
published layout. (tests/ is on sys.path: pytest puts the folder of tests/conftest.py there.)"""

import numpy as np
from scipy.io import savemat

# (x, y, polarity, timestamp_us, label) per recording; addresses 1-based as MATLAB writes them
RECORDINGS = [
    ([1, 32, 1, 3], [1, 2, 1, 32], [1, -1, -1, 1], [100, 300, 50, 450], "A"),
    ([5], [6], [1], [1000], "A"),
    ([2, 3], [2, 3], [1, 1], [0, 400], "b"),  # lower case is read as B
    ([], [], [], [], "B"),  # a recording without events: every pixel silent
    ([7], [7], [1], [20], "7"),  # the only 7: stays in train
]


def write_mat(path, recordings=RECORDINGS, cells=False, fields=("x", "y", "p", "ts", "label")):
    """A .mat file holding ROI as a 1 x n struct array (or a cell array of 1 x 1 structs)."""
    dtype = [(name, object) for name in fields]
    rows = [
        tuple(([np.array([v], dtype=float) for v in r[:4]] + list(r[4:]))[: len(fields)])
        for r in recordings
    ]
    if cells:
        roi = np.empty((1, len(rows)), dtype=object)
        for k, row in enumerate(rows):
            struct = np.empty((1, 1), dtype=dtype)
            struct[0, 0] = row
            roi[0, k] = struct
    else:
        roi = np.empty((1, len(rows)), dtype=dtype)
        for k, row in enumerate(rows):
            roi[0, k] = row
    savemat(path, {"ROI": roi})
    return path
