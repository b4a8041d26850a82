"""The ego vehicle's motion read from a trajectory file and interpolated per pulse.

A trajectory file holds one pose a line, time first (the layout of HELIOS++'s interpolated
platforms, whose default column order and ',' separator it shares):

    # t_s   x_m   y_m   z_m   roll_deg  pitch_deg  yaw_deg
    0.00    0.0   0.0   0.0   0.0       0.0        0.0
    0.01    0.1   0.0   0.0   0.0       0.0        0.3

seconds, metres in the scene frame (x forward along the road, y left, z up) and degrees
(:mod:`simlidar.motion.rotations`: R = Rz(yaw) Ry(pitch) Rx(roll)); values separated by
whitespace or commas; '#' starts a comment; blank lines are skipped. Between two rows the
position moves linearly and the rotation by slerp, at a constant rate: the interpolation of
ROS's ``tf2`` between two transforms of its buffer.
"""

import hashlib
import math
import re
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simlidar.content import read_text
from simlidar.errors import ConfigError, shown
from simlidar.motion.poses import Poses
from simlidar.motion.rotations import (
    quaternion_from_rpy,
    rotation_from_quaternion,
    shorter_arc,
    slerp_on_arc,
)

COLUMNS = ("t", "x", "y", "z", "roll", "pitch", "yaw")
# A trajectory file's size: a row written with 6 decimals is about 67 bytes, so 16 MiB holds
# 250,000 rows, 40 minutes at 100 Hz (an IMU/GNSS log's rate; KITTI's OXTS logs are 10 and
# 100 Hz) or 4 minutes at 1 kHz, against 10 s for a sequence of 100 frames at 10 Hz. The worst
# file of this size to scan, 16.7 million blank or comment lines, takes 0.2 s.
MAX_TRAJECTORY_BYTES = 16 * 2**20
# Rows of one file, as many as MAX_TRAJECTORY_BYTES holds of such rows: a file of short rows
# ("0 0 0 0 0 0 0", 14 bytes) would fit 1.2 million. Bounds the parsing (about 2 s for 250,000
# rows on a loaded 2-core machine) and the memory (64 bytes a row while parsing).
MAX_TRAJECTORY_ROWS = 250_000
# Times, seconds: float64's spacing at 2^32 s is 2^-20 s = 0.95 us, still below the 2.304 us
# between two of a VLP-16's firings, so pulses keep distinct times; GNSS seconds of the week and
# Unix times until 2106 fit. Beyond, t1 - t0 could overflow to inf (1e308 - -1e308).
MAX_TIME_S = 2.0**32
# Positions, metres from the scene's origin: the ray caster's scene cell reaches 150 m from the
# sensor (simlidar.scene.build.CELL_HALF_EXTENT_M) and a sweep checks the real reach; beyond
# 1 km a position is a mistake of units or of origin (a GNSS log's UTM coordinates are
# 10^5 - 10^7 m), refused here with the line that holds it.
MAX_POSITION_M = 1000.0
# The most an angle may change between two rows, degrees: slerp turns the shorter way, so a
# step of 180 degrees or more (a wrap from 179 to -179, or a true turn of 200) cannot be told
# from a turn the other way. Rows must say the way: unwrapped angles, rows close enough.
MAX_ANGLE_STEP_DEG = 180.0

# A decimal number as a trajectory file writes it (float() would also take "nan", "inf",
# "1_000" and digits of other scripts), and a separator; possessive, so that a hostile line of
# millions of digits or blanks is matched in one pass, without backtracking
_NUMBER = r"[+-]?(?:\d++(?:\.\d*+)?|\.\d++)(?:[eE][+-]?\d++)?"
_SEPARATOR = r"(?>\s*+,\s*+|\s++)"
_ROW = re.compile(f"({_NUMBER})" + f"{_SEPARATOR}({_NUMBER})" * 6, re.ASCII)
_FIELDS = re.compile(_SEPARATOR, re.ASCII)
# What is left of a line once comments are gone, from its first character that is not blank
_ROW_TEXT = re.compile(r"\S[^\n]*+")
_COMMENT = re.compile(r"#[^\n]*+")
_LAYOUT = "t x y z roll pitch yaw (seconds, metres, degrees)"


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses at K times, interpolated in between: :meth:`poses` gives the body's pose at any
    time of ``[t_s[0], t_s[-1]]``, as :meth:`simlidar.motion.poses.PlanarMotion.poses` does."""

    t_s: np.ndarray  # (K,) float64 seconds, strictly increasing, K >= 2
    positions_m: np.ndarray  # (K, 3) float64: the body's origin in the scene frame
    quaternions: np.ndarray  # (K, 4) float64 (w, x, y, z), unit: the body's rotation
    source: str = "trajectory"  # what errors name: the file it was read from

    def __post_init__(self):
        for name in ("t_s", "positions_m", "quaternions"):
            # a copy, read-only: the caller's array may change, the poses must not
            values = np.array(getattr(self, name), dtype=np.float64)
            if not np.isfinite(values).all():
                raise ConfigError(f"{self.source}: {name}: expected finite numbers")
            values.flags.writeable = False
            object.__setattr__(self, name, values)
        k = len(self.t_s) if self.t_s.ndim == 1 else 0
        shapes = (self.t_s.shape, self.positions_m.shape, self.quaternions.shape)
        if k < 2 or shapes[1:] != ((k, 3), (k, 4)):
            raise ConfigError(
                f"{self.source}: arrays of shapes {shapes}, "
                "expected (K,), (K, 3) and (K, 4) with K >= 2"
            )
        if not np.all(np.diff(self.t_s) > 0):
            raise ConfigError(f"{self.source}: t_s: expected times that strictly increase")
        # slerp's angle between two quaternions holds for unit ones only
        if not np.allclose(np.sum(self.quaternions**2, axis=-1), 1.0, rtol=0.0, atol=1e-9):
            raise ConfigError(f"{self.source}: quaternions: expected unit quaternions")
        # each pair of consecutive rows' arc, (K - 1, 4) and (K - 1,): once, not per pulse
        object.__setattr__(self, "_arcs", shorter_arc(self.quaternions[:-1], self.quaternions[1:]))

    @classmethod
    def from_rows(cls, rows: np.ndarray, source: str = "trajectory") -> "Trajectory":
        """The trajectory of :meth:`rows` (a sweep's dataset ``ego_trajectory``)."""
        rows = np.asarray(rows, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != 8:
            raise ConfigError(f"{source}: rows of shape {rows.shape}, expected (K, 8)")
        return cls(rows[:, 0], rows[:, 1:4], rows[:, 4:], source)

    def rows(self) -> np.ndarray:
        """The trajectory as a sweep stores it (dataset ``ego_trajectory``): (K, 8) float64
        rows of t_s, x_m, y_m, z_m and the rotation's unit quaternion w, x, y, z."""
        return np.concatenate([self.t_s[:, None], self.positions_m, self.quaternions], axis=1)

    def summary(self) -> dict:
        """What a configuration stores of the trajectory: its rows and the sha256 of its poses
        (:meth:`rows` as little-endian float64)."""
        rows = self.rows()
        digest = hashlib.sha256(rows.astype("<f8").tobytes()).hexdigest()
        return {"rows": len(rows), "sha256": digest}

    def check_covers(self, start_s: float, stop_s: float, where: str | None = None) -> None:
        """Refuse (ConfigError naming ``where``, default the file) a span of times ``[start_s,
        stop_s]`` seconds that the trajectory's times do not cover."""
        first, last = float(self.t_s[0]), float(self.t_s[-1])
        if not first <= start_s <= stop_s <= last:
            raise ConfigError(
                f"{where or self.source}: poses from {shown(first)} s to {shown(last)} s, "
                f"expected them to cover the simulated span {shown(float(start_s))} s to "
                f"{shown(float(stop_s))} s"
            )

    def poses(self, t_s) -> Poses:
        """The body's poses at times ``t_s`` (*S,) seconds: (*S) poses mapping its frame to the
        scene's. Between rows k and k + 1 (t_k <= t <= t_k+1, f = (t - t_k) / (t_k+1 - t_k))
        the position is (1 - f) p_k + f p_k+1 and the rotation slerp(q_k, q_k+1, f); at a row's
        time, exactly the row's pose. A time outside the rows' is a ConfigError
        (:meth:`check_covers` says it before any pulse is cast)."""
        t = np.asarray(t_s, dtype=np.float64)
        if t.size:
            self.check_covers(float(t.min()), float(t.max()))  # NaN fails too
        # the row at or before each time; the last row's time interpolates from the one before
        k = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self.t_s) - 2)
        t0, t1 = self.t_s[k], self.t_s[k + 1]  # each (*S,)
        f = (t - t0) / (t1 - t0)  # (*S,) in [0, 1]: rounding is monotonic, t0 <= t <= t1
        # (1 - f) p0 + f p1 rather than p0 + f (p1 - p0): exact at both ends
        p0, p1 = self.positions_m[k], self.positions_m[k + 1]  # each (*S, 3)
        position = (1.0 - f)[..., None] * p0 + f[..., None] * p1
        ends, angles = self._arcs
        quaternion = slerp_on_arc(self.quaternions[k], ends[k], angles[k], f)  # (*S, 4)
        rotation = rotation_from_quaternion(quaternion)
        return Poses(rotation, position)


def _refuse_row(where: str, line: int, text: str) -> None:
    """Raise the ConfigError that says why ``text``, line ``line`` of a trajectory file, is not
    a row of 7 finite numbers."""
    fields = _FIELDS.split(text)
    if len(fields) != len(COLUMNS):
        raise ConfigError(
            f"{where} line {line}: {len(fields)} values, expected {len(COLUMNS)}: {_LAYOUT}"
        )
    for column, field in zip(COLUMNS, fields):
        # not a number at all, or beyond float64's 1.8e308
        if not (re.fullmatch(_NUMBER, field, re.ASCII) and math.isfinite(float(field))):
            raise ConfigError(
                f"{where} line {line}: {column} {shown(field)}: expected a finite decimal number"
            )
    raise ConfigError(f"{where} line {line}: {shown(text)}: expected a row of {_LAYOUT}")


def load_trajectory(path: str | Path, where: str | None = None) -> Trajectory:
    """The trajectory of a file of rows ``t x y z roll pitch yaw`` (module docstring), read
    with :func:`simlidar.content.read_text` (a regular file of at most
    :data:`MAX_TRAJECTORY_BYTES`). Every refusal is a one-line ConfigError starting with
    ``where`` (default: the path) and naming the line: a row without exactly 7 numbers, a value
    that is not a finite decimal number, more than :data:`MAX_TRAJECTORY_ROWS` rows or fewer
    than 2, times that do not strictly increase or lie beyond +-:data:`MAX_TIME_S`, a position
    beyond +-:data:`MAX_POSITION_M` along an axis, an angle that changes by
    :data:`MAX_ANGLE_STEP_DEG` or more from one row to the next."""
    path = Path(path)
    where = where or str(path)
    # comments blanked first (the line breaks stay), so that the loop below visits rows only:
    # a file of millions of blank or comment lines costs two scans in C, not a Python loop
    text = _COMMENT.sub("", read_text(path, MAX_TRAJECTORY_BYTES, ConfigError, where))
    rows, lines = array("d"), array("q")  # each row's 7 values; its line number, 1-based
    line, seen = 1, 0  # the line number at offset ``seen`` of the text
    for found in _ROW_TEXT.finditer(text):
        # lines are counted at "\n" only, as editors number them (str.splitlines would also
        # break at "\x0c", "\u2028", ...)
        line += text.count("\n", seen, found.start())
        seen = found.start()
        if len(lines) == MAX_TRAJECTORY_ROWS:
            raise ConfigError(
                f"{where} line {line}: expected at most {MAX_TRAJECTORY_ROWS} pose rows"
            )
        row = found.group().rstrip()
        match = _ROW.fullmatch(row)
        values = list(map(float, match.groups())) if match else []
        if not (values and all(map(math.isfinite, values))):
            _refuse_row(where, line, row)
        rows.extend(values)
        lines.append(line)
    if len(lines) < 2:
        raise ConfigError(f"{where}: expected at least 2 pose rows ({_LAYOUT}), got {len(lines)}")
    values = np.frombuffer(rows, dtype=np.float64).reshape(-1, len(COLUMNS))  # (K, 7)
    _check_rows(where, values, np.frombuffer(lines, dtype=np.int64))
    t, position, (roll, pitch, yaw) = values[:, 0], values[:, 1:4], values[:, 4:].T
    return Trajectory(t, position, quaternion_from_rpy(roll, pitch, yaw), where)


def _check_rows(where: str, values: np.ndarray, lines: np.ndarray) -> None:
    """Refuse the first row of ``values`` (K, 7) that breaks a rule of :func:`load_trajectory`
    that spans rows or bounds a value, naming its line (``lines``, (K,))."""

    def first(bad: np.ndarray) -> int | None:
        return int(np.argmax(bad)) if bad.any() else None

    t = values[:, 0]
    if (row := first(np.abs(t) > MAX_TIME_S)) is not None:
        raise ConfigError(
            f"{where} line {lines[row]}: t {shown(float(t[row]))} s: expected seconds within "
            f"+-{MAX_TIME_S:.0f}"
        )
    if (row := first(np.diff(t) <= 0)) is not None:
        raise ConfigError(
            f"{where} line {lines[row + 1]}: t {shown(float(t[row + 1]))} s after "
            f"{shown(float(t[row]))} s on line {lines[row]}: expected times that strictly increase"
        )
    for column in range(1, 4):
        if (row := first(np.abs(values[:, column]) > MAX_POSITION_M)) is not None:
            raise ConfigError(
                f"{where} line {lines[row]}: {COLUMNS[column]} {shown(float(values[row, column]))}"
                f" m: expected metres within +-{MAX_POSITION_M:.0f} of the scene's origin"
            )
    for column in range(4, 7):
        angle = values[:, column]
        if (row := first(np.abs(np.diff(angle)) >= MAX_ANGLE_STEP_DEG)) is not None:
            raise ConfigError(
                f"{where} line {lines[row + 1]}: {COLUMNS[column]} "
                f"{shown(float(angle[row + 1]))} after {shown(float(angle[row]))} on line "
                f"{lines[row]}: expected consecutive rows less than {MAX_ANGLE_STEP_DEG:.0f} "
                "degrees apart (slerp turns the short way; write angles unwrapped, 190 after 170)"
            )
