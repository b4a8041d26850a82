"""The checks of a stream split's ragged events (docs/streams.md, "Loading streams"): the
offsets tile the events (:func:`event_problems`) and every event's values lie within its
sensor's window and span (:func:`event_limits`, :func:`event_value_problems`). The loaders of
:mod:`simlidar.dataset.stream_loaders` and ``simlidar verify`` run the same checks and name a
problem the same way."""

import numpy as np

from simlidar.errors import shown


def event_problems(path, start: np.ndarray, count: np.ndarray, total: int) -> list[str]:
    """The problem of a split's ragged events, starting with ``path``, if sample i's events
    (``start`` (N,), ``count`` (N,): ``event_start``, ``event_count``) are not the rows
    start[i] .. start[i] + count[i] of the ``total`` events, each sample's following the
    previous one's from row 0 to the last: an empty list where they are."""
    start, count = np.asarray(start), np.asarray(count)
    # a count above total is refused before the sum, so that no int64 sum wraps around
    ends = np.cumsum(np.clip(count, 0, total))
    bad = (count < 0) | (count > total) | (start != ends - count) | (ends > total)
    if len(count) and not bad.any() and ends[-1] != total:
        bad[-1] = True
    if not bad.any() and (len(count) or not total):
        return []
    where = "no samples"
    if bad.any():
        i = int(np.argmax(bad))
        first, many = int(start[i]), int(count[i])
        where = f"sample {i}: rows {first} .. {first + many}"
    return [
        f"{path}: 'event_start' and 'event_count' do not tile the {total} events in order "
        f"({where}); expected each sample's rows to follow the previous sample's, from row 0 "
        f"to row {total}"
    ]


def event_limits(attrs: dict, height: int, width: int) -> dict[str, float]:
    """The largest value each checked event field may take, by a stream split's attributes and
    its delays' ``height`` x ``width`` (R W): a column of the window, a row, the one polarity,
    a surface of ``surface_names``, and an arrival within the span plus the longest time of
    flight."""
    return {
        "x": width // int(attrs["rotations"]) - 1,
        "y": height - 1,
        "p": 0,
        "surface": len(attrs["surface_names"]) - 1,
        "t_us": float(attrs["span_us"]) + float(attrs["tof_max_ns"]) / 1000.0,
    }


EVENT_BLOCK = 2**22  # events checked at a time by event_value_problems


def event_value_problems(path, f, limits: dict[str, float]) -> list[str]:
    """The first event of an open stream split ``f`` (of tiled offsets) whose field lies outside
    :func:`event_limits` or is NaN, named as the loaders name it (``simlidar verify``'s check of
    the values the loaders check as they read); the events read ``EVENT_BLOCK`` at a time."""
    start, count = f["event_start"][:], f["event_count"][:]
    total = f["event_t_us"].shape[0]
    for first in range(0, total, EVENT_BLOCK):
        rows = slice(first, min(first + EVENT_BLOCK, total))
        found = first_outside({n: f[f"event_{n}"][rows] for n in limits}, limits)
        if found is not None:
            row, problem = found[0] + first, found[1]
            sample = int(np.searchsorted(start + count, row, side="right"))
            return [f"{path} (sample {sample}, its event {row - start[sample]}): {problem}"]
    return []


_MEANING = {
    "x": "a column of the window",
    "y": "a row",
    "p": "the one polarity",
    "surface": "an index into surface_names",
    "t_us": "an arrival within span_us plus the longest time of flight",
}


def first_outside(events: dict[str, np.ndarray], limits: dict[str, float]):
    """The row of the first of ``events`` (per-event arrays by name) with a field of ``limits``
    outside 0 .. its limit or NaN, and what is wrong with it, (row, problem); None where there
    is none."""
    first = None
    for name, limit in limits.items():
        bad = ~((events[name] >= 0) & (events[name] <= limit)) if name in events else None
        if bad is not None and bad.any() and (first is None or np.argmax(bad) < first[0]):
            row = int(np.argmax(bad))
            value = shown(events[name][row].item())
            first = (row, f"event_{name} {value}; expected {_MEANING[name]}, 0 .. {limit:.10g}")
    return first
