"""What a stream network reads: a recipe's ``[stream]`` table (:mod:`simlidar.models.stream_nets`
describes the inputs). No torch: the registry checks recipes without it."""

from dataclasses import dataclass, fields, replace

from simlidar.errors import ConfigError

ROTATIONS, BINS = "rotations", "bins"
INPUTS = (ROTATIONS, BINS)
BIN_MS = (0.05, 10.0)  # a bin's length, ms: from a few columns' firing to a window's burst


@dataclass(frozen=True)
class StreamSpec:
    """What a stream network reads (:mod:`simlidar.models.stream_nets`)."""

    input: str = ROTATIONS
    bin_ms: float = 1.0

    def __post_init__(self):
        if self.input not in INPUTS:
            raise ConfigError(f"input={self.input!r}: expected one of {list(INPUTS)}")
        bin_ms = self.bin_ms
        if (
            isinstance(bin_ms, bool)
            or not isinstance(bin_ms, int | float)
            or not (BIN_MS[0] <= bin_ms <= BIN_MS[1])
        ):
            raise ConfigError(f"bin_ms={bin_ms!r}: expected a number in [{BIN_MS[0]}, {BIN_MS[1]}]")

    @property
    def channels(self) -> int:
        """The input's channels: 1 for rotations, 2 (events, nearness) for bins."""
        return 1 if self.input == ROTATIONS else 2

    def table(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def stream_spec_of(recipe: dict, where: str | None = None) -> StreamSpec | None:
    """The StreamSpec of a recipe's ``[stream]`` table (None: a window model's recipe);
    ConfigError starting with ``where`` (default: the recipe's name) for a bad table."""
    table = recipe.get("stream")
    if table is None:
        return None
    where = where or f"recipe {recipe.get('name', '?')}"
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: key 'stream': expected a table, got {table!r}")
    names = [f.name for f in fields(StreamSpec)]
    unknown = sorted(set(table) - set(names))
    if unknown:
        raise ConfigError(f"{where}: unknown key 'stream.{unknown[0]}': expected one of {names}")
    try:
        return replace(StreamSpec(), **table)
    except ConfigError as exc:
        raise ConfigError(f"{where}: [stream] {exc}") from None
