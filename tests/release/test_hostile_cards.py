"""A card's front matter from elsewhere (issue 40, item 2): read in bounded memory and time.

Attack list, each a dataset's README.md rewritten by the test and checked by ``simlidar verify``
(which pack and fetch run first): a "billion laughs" (aliases nine deep: 10^9 strings once
expanded, 3.8 GB and a MemoryError before), a front matter nested 20,000 deep (a RecursionError
traceback before) and a 3 GiB sparse card with a valid head (read whole before). Each is one
``FAILED`` line naming the card and what was expected, exit 1, in well under a second or two.
"""

import shutil
import time

import pytest

from simlidar.release.card import MAX_CARD_BYTES, MAX_FRONT_MATTER_DEPTH
from simlidar.release.checksums import SUMS, write_sums


@pytest.fixture
def copy(datasets, tmp_path):
    target = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], target)
    return target


def _one_failed_line(cli, copy, *lines):
    """verify's FAILED lines about the card: exactly ``lines``, exit 1, quickly."""
    start = time.monotonic()
    result = cli("verify", copy)
    assert time.monotonic() - start < 20
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    card = [line for line in result.output.splitlines() if "README.md" in line]
    assert card == [f"FAILED {copy / 'README.md'}: {line}" for line in lines], result.output


def _front_matter(copy, yaml_text):
    card = copy / "README.md"
    text = card.read_text()
    card.write_text(f"---\n{yaml_text}" + text[text.index("\n---\n", 3) + 1 :])
    write_sums(copy, ["README.md"])


def test_a_billion_laughs_card_is_refused_before_any_alias_is_expanded(copy, cli):
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 10)}]" for k in range(1, 10)]
    _front_matter(copy, "\n".join(lines) + "\ndataset_info: *a9\n")
    _one_failed_line(
        cli,
        copy,
        "front matter YAML anchor or alias ('&' or '*') at line 1; expected plain YAML "
        "without anchors or aliases",
    )


def test_a_card_nested_20000_deep_is_refused_in_one_line(copy, cli):
    _front_matter(copy, "license: x\ndataset_info: " + "[" * 20_000 + "]" * 20_000 + "\n")
    assert MAX_FRONT_MATTER_DEPTH == 64
    _one_failed_line(
        cli, copy, "front matter nested deeper than 64 levels at line 2; expected at most 64"
    )


def test_a_sparse_3_gib_card_is_never_read_whole(copy, cli):
    card = copy / "README.md"
    with card.open("r+b") as f:  # a valid card, then 3 GiB of holes (no disk used)
        f.truncate(3 * 2**30)
    (copy / SUMS).unlink()  # (hashing 3 GiB would take seconds: the card is the problem here)
    assert MAX_CARD_BYTES == 4 * 2**20
    _one_failed_line(
        cli, copy, f"expected a file of at most {MAX_CARD_BYTES} bytes, got {3 * 2**30} bytes"
    )
