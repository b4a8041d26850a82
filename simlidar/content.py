"""Where the declarative content folders (``scenes/``, ``baselines/``, ``benchmark/``) live.

In a wheel they are packaged as ``simlidar/_content/<name>``; in a source checkout (and an
editable install) they are the top-level folders beside the package.
"""

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def content_dir(name: str) -> Path:
    """Return the folder of the shipped content ``name`` (``"scenes"``, ``"baselines"``, ...)."""
    packaged = _PACKAGE / "_content" / name
    if packaged.is_dir():
        return packaged
    return _PACKAGE.parent / name
