"""Bad input ends in one line and exit code 1 (2 for a bad option value), never a traceback,
and leaves nothing behind: one test per case that used to crash or give a wrong result.

Attack list of cases 10 and 14 (issue 35, items 6 and 8): a malformed SHA256SUMS given to
``card`` (which must write nothing); an archive, served over HTTP on loopback, whose dataset
carries ``payload/run_me.sh``: fetch fails at its verify step and installs nothing.
"""

import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
import warnings

import convert.conftest as kitti_fixtures
import dataset.test_archive as archive_tests
import h5py
import pytest
from click.testing import CliRunner

from simlidar.cli import main
from simlidar.convert import convert_kitti
from simlidar.errors import ConfigError
from simlidar.release.archive import fetch
from simlidar.release.checksums import SUMS, write_sums

SMALL = ["--train-size", "32", "--test-size", "32"]
# Fixtures reused from the archive and converter tests (pytest puts tests/ on sys.path).
server, packed = archive_tests.server, archive_tests.packed
synthetic_kitti = kitti_fixtures.synthetic_kitti


@pytest.fixture(autouse=True)
def _restore_showwarning(monkeypatch):
    """main() sends warnings to stderr as one line; undo that after each test."""
    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _error_lines(result) -> list[str]:
    """The output's "Error: " lines, after checking that no exception escaped."""
    assert "Traceback" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(
        result.exception
    )
    return [line for line in result.output.splitlines() if line.startswith("Error: ")]


def _copy(datasets, tmp_path):
    copy = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], copy)
    return copy


# 1. fetch --timeout inf / 1e300 / nan: a bad option value, before anything is created.
def test_1_fetch_refuses_absurd_timeouts(server, packed, tmp_path):
    url = f"{server[0]}/{packed[0].name}"
    out = tmp_path / "data"
    for timeout in ("inf", "1e300", "nan", "86401"):
        result = _run("fetch", url, "--out", out, "--timeout", timeout)
        assert result.exit_code == 2, result.output
        (line,) = _error_lines(result)
        assert "Invalid value for '--timeout'" in line and "0.1<=x<=86400" in line
        assert not out.exists()
    with pytest.raises(ConfigError, match=r"timeout=inf: expected seconds in \(0, 86400\]"):
        fetch(url, out=out, timeout=float("inf"), progress=False)
    assert not out.exists()
    result = _run("fetch", url, "--out", out, "--timeout", "86400")  # a day is fine
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [packed[0].name.removesuffix(".tar.gz")]


# 2. A fetch killed with -9 leaves a locked temporary that the next fetch removes, with a
# warning; pack's temporary is unique, so another process's (same PID) is never touched.
def test_2_a_killed_fetchs_temporary_is_removed_by_the_next_one(server, packed, tmp_path):
    url, _ = server
    out = tmp_path / "data"
    command = ["fetch", f"{url}/hang/x.tar.gz", "--sha256", "0" * 64, "--out", str(out)]
    child = subprocess.Popen(
        [sys.executable, "-m", "simlidar.cli", *command, "--timeout", "60"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while not (out.is_dir() and any(p.is_dir() for p in out.iterdir())):  # downloading
            assert time.monotonic() < deadline and child.poll() is None, "fetch never started"
            time.sleep(0.05)
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    left = sorted(p.name for p in out.iterdir())
    assert len(left) == 2 and left[0].startswith(".x.fetch-") and left[1] == left[0] + ".lock"
    result = _run("fetch", f"{url}/{packed[0].name}", "--out", out)
    assert result.exit_code == 0, result.output
    assert f"Warning: removed {out / left[0]}, left by a run that did not finish" in result.output
    assert sorted(p.name for p in out.iterdir()) == [packed[0].name.removesuffix(".tar.gz")]


def test_2_pack_never_collides_with_another_process_temporary(datasets, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    theirs = out / f".{datasets[0.1].name}.tar.gz.partial-{os.getpid()}"  # same PID, elsewhere
    theirs.mkdir()
    result = _run("pack", datasets[0.1], "--out", out)
    assert result.exit_code == 0, result.output
    assert theirs.is_dir()
    assert sorted(p.name for p in out.iterdir() if p != theirs) == [
        f"{datasets[0.1].name}.tar.gz",
        f"{datasets[0.1].name}.tar.gz.sha256",
    ]
    assert (out / f"{datasets[0.1].name}.tar.gz").stat().st_mode & 0o777 == 0o644


# 3. convert kitti: resolutions and the range that give no meaningful front view.
@pytest.mark.parametrize(
    "option, value, expected",
    [
        ("--res-v", "1e-300", "1e-300 is not in the range 0.01<=x<=10"),
        ("--res-h", "1e-300", "1e-300 is not in the range 0.01<=x<=10"),
        ("--res-v", "inf", "inf is not in the range 0.01<=x<=10"),
        ("--max-range", "1e-300", "1e-300 is not in the range 1<=x<=1000"),
        ("--max-range", "nan", "'nan' is not a number in the range 1<=x<=1000"),
    ],
)
def test_3_kitti_options_that_mean_nothing_are_refused(
    synthetic_kitti,
    tmp_path,
    option,
    value,
    expected,
):
    out = tmp_path / "out"
    result = _run("convert", "kitti", synthetic_kitti, "--out", out, option, value)
    assert result.exit_code == 2, result.output
    (line,) = _error_lines(result)
    assert f"Invalid value for '{option}': {expected}" in line
    assert not out.exists()
    field = {"--res-h": "res_h_deg", "--res-v": "res_v_deg", "--max-range": "max_range_m"}
    with pytest.raises(ConfigError, match=f"{field[option]}="):
        convert_kitti(synthetic_kitti, out, **{field[option]: float(value)}, progress=False)
    assert not out.exists()


# 4. A card (or SHA256SUMS) that is not UTF-8: one problem, named, no UnicodeDecodeError.
def test_4_a_card_that_is_not_utf8_is_one_problem(datasets, tmp_path):
    copy = _copy(datasets, tmp_path)
    card = copy / "README.md"
    card.write_bytes(card.read_bytes().replace(b"---\n", b"---\n# caf\xe9\n", 1))
    write_sums(copy, ["README.md"])  # the checksums agree: the encoding is the only problem
    result = _run("verify", copy)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    failed = [line for line in result.output.splitlines() if line.startswith("FAILED")]
    assert len(failed) == 1 and failed[0].startswith(f"FAILED {card}: not UTF-8 text (")
    assert failed[0].endswith("expected the dataset card in UTF-8")
    out = tmp_path / "out"
    result = _run("pack", copy, "--out", out)
    assert result.exit_code == 1
    (line,) = _error_lines(result)
    assert line.startswith(f"Error: {card}: not UTF-8 text")
    assert not out.exists()
    (copy / SUMS).write_bytes((copy / SUMS).read_bytes() + b"\xff\n")
    result = _run("verify", copy)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"FAILED {copy / SUMS}: not UTF-8 text (invalid start byte at byte" in result.output


# 5. info on labels outside the class list: one line naming the file and the labels.
def test_5_info_names_bad_labels(datasets, tmp_path):
    copy = _copy(datasets, tmp_path)
    with h5py.File(copy / "train.h5", "r+") as f:
        f["labels"][3] = -1
        f["labels"][5] = 99
    for args in (["info", copy], ["info", copy, "--json"]):
        result = _run(*args)
        assert result.exit_code == 1, result.output
        (line,) = _error_lines(result)
        assert line.startswith(f"Error: {copy / 'train.h5'}: labels -1, 99 outside 0..31")
        assert result.stdout == ""


# 6. OS litter in a dataset: ignored by verify, left out of the archive.
def test_6_os_litter_is_ignored_and_not_packed(datasets, tmp_path):
    copy = _copy(datasets, tmp_path)
    sums = (copy / SUMS).read_bytes()
    litter = [".DS_Store", "Thumbs.db", "desktop.ini", "._train.h5"]
    for name in litter:
        (copy / name).write_bytes(b"\0\x05\x16\x07")
    result = _run("verify", copy)
    assert result.exit_code == 0, result.output
    out = tmp_path / "out"
    result = _run("pack", copy, "--out", out)
    assert result.exit_code == 0, result.output
    with tarfile.open(out / f"{copy.name}.tar.gz") as tar:
        names = {name.split("/")[-1] for name in tar.getnames()}
    assert names.isdisjoint(litter) and "train.h5" in names
    assert (copy / SUMS).read_bytes() == sums


# 7. generate --out "": a bad option value, not the current folder.
def test_7_generate_refuses_an_empty_out(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = _run("generate", *SMALL, "--out", "")
    assert result.exit_code == 2, result.output
    (line,) = _error_lines(result)
    assert "Invalid value for '--out': '' is empty" in line
    assert list(tmp_path.iterdir()) == []


# 10. card with a malformed SHA256SUMS: one line, and nothing written (neither the card nor
# the checksums).
def test_10_card_with_malformed_checksums_writes_nothing(datasets, tmp_path):
    copy = _copy(datasets, tmp_path)
    (copy / "README.md").write_text((copy / "README.md").read_text() + "edited\n")
    (copy / SUMS).write_text("not a checksum line\n")
    before = {p.name: p.read_bytes() for p in copy.iterdir()}
    result = _run("card", copy)
    assert result.exit_code == 1
    (line,) = _error_lines(result)
    assert line == (
        f"Error: {copy / SUMS}: line 1 is not '<sha256>  <file name>'; nothing written "
        "(simlidar verify names the rest)"
    )
    assert {p.name: p.read_bytes() for p in copy.iterdir()} == before


# 14. A fetched dataset carrying a subfolder (payload/run_me.sh): refused at fetch's verify
# step, nothing installed (it used to install and verify OK).
def test_14_a_dataset_carrying_a_subfolder_is_not_installed(server, datasets, tmp_path):
    import hashlib
    import io

    url, root = server
    name = datasets[0.1].name
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        tar.add(datasets[0.1], arcname=name)
        script = b"#!/bin/sh\necho owned\n"
        info = tarfile.TarInfo(f"{name}/payload/run_me.sh")
        info.size, info.mode = len(script), 0o755
        tar.addfile(info, io.BytesIO(script))
    (root / f"{name}.tar.gz").write_bytes(buffer.getvalue())
    digest = hashlib.sha256(buffer.getvalue()).hexdigest()
    out = tmp_path / "data"
    result = _run("fetch", f"{url}/{name}.tar.gz", "--sha256", digest, "--out", out)
    assert result.exit_code == 1, result.output
    (line,) = _error_lines(result)
    assert line.startswith("Error: fetch failed at verify: ") and "payload: is a folder" in line
    assert not out.exists() or not any(out.iterdir())
