"""Bad input ends in one line and exit code 1 (2 for a bad option value), never a traceback,
and leaves nothing behind: one test per case that used to crash or give a wrong result.

Attack list of cases 8-13 (issue 35, items 3 and 6; the class of each, every attribute a
reader parses, is fuzzed in tests/test_broken_datasets.py): a ``config`` attribute that is not
JSON (verify, info, preview, train, bench, card; pack must refuse it); 2-D labels (info,
card); a malformed SHA256SUMS (card, which must write nothing); ``seeds =
[99999999999999999999999]`` in a suite that generates its datasets (refused before any is
written); an HDF5 bomb given to train and bench; a split read by a process that cannot hold
it (a real process under an address-space limit just above its own size). Case 14 (item 8):
an archive, served over HTTP on loopback, whose dataset carries ``payload/run_me.sh``: fetch
fails at its verify step and installs nothing.
"""

import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
import warnings

import h5py
import numpy as np
import pytest

from simlidar.convert import convert_kitti
from simlidar.errors import ConfigError
from simlidar.release.archive import fetch
from simlidar.release.checksums import SUMS, write_sums

SMALL = ["--train-size", "32", "--test-size", "32"]


@pytest.fixture(autouse=True)
def _restore_showwarning(monkeypatch):
    """main() sends warnings to stderr as one line; undo that after each test."""
    monkeypatch.setattr(warnings, "showwarning", warnings.showwarning)


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
def test_fetch_refuses_absurd_timeouts(server, packed, tmp_path, cli):
    url = f"{server[0]}/{packed[0].name}"
    out = tmp_path / "data"
    for timeout in ("inf", "1e300", "nan", "86401"):
        result = cli("fetch", url, "--out", out, "--timeout", timeout)
        assert result.exit_code == 2, result.output
        (line,) = _error_lines(result)
        assert "Invalid value for '--timeout'" in line and "0.1<=x<=86400" in line
        assert not out.exists()
    with pytest.raises(ConfigError, match=r"timeout=inf: expected seconds in \(0, 86400\]"):
        fetch(url, out=out, timeout=float("inf"), progress=False)
    assert not out.exists()
    result = cli("fetch", url, "--out", out, "--timeout", "86400")  # a day is fine
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [packed[0].name.removesuffix(".tar.gz")]


# 2. A fetch killed with -9 leaves a locked temporary that the next fetch removes, with a
# warning; pack's temporary is unique, so another process's (same PID) is never touched.
def test_a_killed_fetchs_temporary_is_removed_by_the_next_one(server, packed, tmp_path, cli):
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
    result = cli("fetch", f"{url}/{packed[0].name}", "--out", out)
    assert result.exit_code == 0, result.output
    assert f"Warning: removed {out / left[0]}, left by a run that did not finish" in result.output
    assert sorted(p.name for p in out.iterdir()) == [packed[0].name.removesuffix(".tar.gz")]


def test_pack_never_collides_with_another_process_temporary(datasets, tmp_path, cli):
    out = tmp_path / "out"
    out.mkdir()
    theirs = out / f".{datasets[0.1].name}.tar.gz.partial-{os.getpid()}"  # same PID, elsewhere
    theirs.mkdir()
    result = cli("pack", datasets[0.1], "--out", out)
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
def test_kitti_options_that_mean_nothing_are_refused(
    synthetic_kitti,
    tmp_path,
    option,
    value,
    expected,
    cli,
):
    out = tmp_path / "out"
    result = cli("convert", "kitti", synthetic_kitti, "--out", out, option, value)
    assert result.exit_code == 2, result.output
    (line,) = _error_lines(result)
    assert f"Invalid value for '{option}': {expected}" in line
    assert not out.exists()
    field = {"--res-h": "res_h_deg", "--res-v": "res_v_deg", "--max-range": "max_range_m"}
    with pytest.raises(ConfigError, match=f"{field[option]}="):
        convert_kitti(synthetic_kitti, out, **{field[option]: float(value)}, progress=False)
    assert not out.exists()


# 4. A card (or SHA256SUMS) that is not UTF-8: one problem, named, no UnicodeDecodeError.
def test_a_card_that_is_not_utf8_is_one_problem(datasets, tmp_path, cli):
    copy = _copy(datasets, tmp_path)
    card = copy / "README.md"
    card.write_bytes(card.read_bytes().replace(b"---\n", b"---\n# caf\xe9\n", 1))
    write_sums(copy, ["README.md"])  # the checksums agree: the encoding is the only problem
    result = cli("verify", copy)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    failed = [line for line in result.output.splitlines() if line.startswith("FAILED")]
    assert failed == [f"FAILED {card}: expected UTF-8 text, got byte 0xe9 at offset 9"]
    out = tmp_path / "out"
    result = cli("pack", copy, "--out", out)
    assert result.exit_code == 1
    (line,) = _error_lines(result)
    assert line == f"Error: {card}: expected UTF-8 text, got byte 0xe9 at offset 9"
    assert not out.exists()
    (copy / SUMS).write_bytes((copy / SUMS).read_bytes() + b"\xff\n")
    result = cli("verify", copy)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"FAILED {copy / SUMS}: not UTF-8 text (invalid start byte at byte" in result.output


# 5. info on labels outside the class list: one line naming the file and the labels.
def test_info_names_labels_outside_the_class_list(datasets, tmp_path, cli):
    copy = _copy(datasets, tmp_path)
    with h5py.File(copy / "train.h5", "r+") as f:
        f["labels"][3] = -1
        f["labels"][5] = 99
    for args in (["info", copy], ["info", copy, "--json"]):
        result = cli(*args)
        assert result.exit_code == 1, result.output
        (line,) = _error_lines(result)
        assert line.startswith(f"Error: {copy / 'train.h5'}: labels -1, 99 outside 0..31")
        assert result.stdout == ""


# 6. OS litter in a dataset: ignored by verify, left out of the archive.
def test_os_litter_is_ignored_and_not_packed(datasets, tmp_path, cli):
    copy = _copy(datasets, tmp_path)
    sums = (copy / SUMS).read_bytes()
    litter = [".DS_Store", "Thumbs.db", "desktop.ini", "._train.h5"]
    for name in litter:
        (copy / name).write_bytes(b"\0\x05\x16\x07")
    result = cli("verify", copy)
    assert result.exit_code == 0, result.output
    out = tmp_path / "out"
    result = cli("pack", copy, "--out", out)
    assert result.exit_code == 0, result.output
    with tarfile.open(out / f"{copy.name}.tar.gz") as tar:
        names = {name.split("/")[-1] for name in tar.getnames()}
    assert names.isdisjoint(litter) and "train.h5" in names
    assert (copy / SUMS).read_bytes() == sums


# 7. generate --out "": a bad option value, not the current folder.
def test_generate_refuses_an_empty_out_instead_of_using_the_current_folder(
    tmp_path, monkeypatch, cli
):
    monkeypatch.chdir(tmp_path)
    result = cli("generate", *SMALL, "--out", "")
    assert result.exit_code == 2, result.output
    (line,) = _error_lines(result)
    assert "Invalid value for '--out': '' is empty" in line
    assert list(tmp_path.iterdir()) == []


def _damaged(datasets, tmp_path, damage):
    """A copy of the small dataset damaged by ``damage(train.h5 open for writing)``, its
    checksums rewritten so that the damage is the only problem."""
    copy = _copy(datasets, tmp_path)
    with h5py.File(copy / "train.h5", "a") as f:
        damage(f)
    write_sums(copy)
    return copy


def _reading_commands(copy, tmp_path):
    return {
        "info": ["info", copy],
        "preview": ["preview", copy, "--out", tmp_path / "p.png"],
        "card": ["card", copy],
        "train": ["train", "--model", "mlp", "--dataset", copy, "--out", tmp_path / "r"],
        "bench": ["bench", "--models", "mlp", "--dataset", copy, "--out", tmp_path / "b"],
    }


# 8. A config attribute that is not JSON: one line from every reading command; pack (which
# verifies first) publishes nothing.
def test_a_config_that_is_not_json_is_one_line_everywhere(datasets, tmp_path, cli):
    def damage(f):
        f.attrs["config"] = "{not json"

    copy = _damaged(datasets, tmp_path, damage)
    message = f"{copy / 'train.h5'}: attribute 'config' is '{{not json'; expected a JSON object"
    result = cli("verify", copy)
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert f"FAILED {message}" in result.output
    for name, command in _reading_commands(copy, tmp_path).items():
        result = cli(*command)
        assert result.exit_code == 1, (name, result.output)
        (line,) = _error_lines(result)
        assert line.startswith(f"Error: {message}"), (name, line)
    out = tmp_path / "out"
    result = cli("pack", copy, "--out", out)
    assert result.exit_code == 1
    (line,) = _error_lines(result)
    assert line.startswith(f"Error: {message}")
    assert not out.exists() or not any(out.iterdir())
    assert not any((tmp_path / n).exists() for n in ("p.png", "r", "b"))


# 9. 2-D labels: info and card name the file and the shape.
def test_two_dimensional_labels_are_one_line(datasets, tmp_path, cli):
    def damage(f):
        labels = f["labels"][:]
        del f["labels"]
        f["labels"] = np.stack([labels, labels], axis=1)

    copy = _damaged(datasets, tmp_path, damage)
    card = (copy / "README.md").read_bytes()
    for command in (["info", copy], ["info", copy, "--json"], ["card", copy]):
        result = cli(*command)
        assert result.exit_code == 1, result.output
        (line,) = _error_lines(result)
        assert line == (f"Error: {copy / 'train.h5'}: 'labels' has shape (96, 2), expected (96,)")
    assert (copy / "README.md").read_bytes() == card


# 10. card with a malformed SHA256SUMS: one line, and nothing written (neither the card nor
# the checksums).
def test_card_with_malformed_checksums_writes_nothing(datasets, tmp_path, cli):
    copy = _copy(datasets, tmp_path)
    (copy / "README.md").write_text((copy / "README.md").read_text() + "edited\n")
    (copy / SUMS).write_text("not a checksum line\n")
    before = {p.name: p.read_bytes() for p in copy.iterdir()}
    result = cli("card", copy)
    assert result.exit_code == 1
    (line,) = _error_lines(result)
    assert line == (
        f"Error: {copy / SUMS}: line 1 is not '<sha256>  <file name>'; nothing written "
        "(simlidar verify names the rest)"
    )
    assert {p.name: p.read_bytes() for p in copy.iterdir()} == before


# 11. A training seed beyond 64 bits in a suite that generates its datasets: refused by the
# suite reader, before any dataset is written (it used to fail after writing them).
def test_a_seed_beyond_64_bits_is_refused_before_anything_is_written(tmp_path, cli):
    suite = tmp_path / "s.toml"
    suite.write_text(
        'models = ["mlp"]\nseeds = [99999999999999999999999]\n[generate]\nnoise = [0.1]\n'
        "train_size = 64\ntest_size = 32\n[budget]\nepochs = 1\nvalidation = 0\n"
    )
    out = tmp_path / "out"
    result = cli("bench", "--suite", suite, "--out", out)
    assert result.exit_code == 2, result.output
    (line,) = _error_lines(result)
    assert line == (
        f"Error: Invalid value for '--suite': suite {suite}: key 'seeds': expected a "
        "non-empty list of integers in "
        "[0, 2**63), got [99999999999999999999999]"
    )
    assert not out.exists()


# 12. An HDF5 bomb (20,000,000 samples declared in a file of a few hundred KB): train and
# bench refuse it in one line instead of "Unable to allocate 19.1 GiB". Real processes under
# an 8 GiB address-space limit, so that a regression fails here instead of taking the machine.
def test_train_and_bench_refuse_an_hdf5_bomb(datasets, tmp_path, limited_python, hdf5_bomb):
    copy = _copy(datasets, tmp_path)
    hdf5_bomb(copy, rows=256)
    commands = _reading_commands(copy, tmp_path)
    limit = 8 * 2**30
    for name in ("train", "bench"):
        result = limited_python(["-m", "simlidar.cli", *commands[name]], limit)
        assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
        (line,) = result.stderr.strip().splitlines()
        assert line.startswith("Error: ") and "Unable to allocate" not in line, line
        assert "declares (20000000,) int32 (76.3 MiB) but stores 0 B" in line, line
    assert not (tmp_path / "r").exists() and not (tmp_path / "b").exists()


# 13. A split larger than the memory the process can still take: one line naming both sizes
# before reading (it was an HDF5 "memory allocation failed" traceback). A real process under
# an address-space limit (ulimit -v) of its own size plus 16 KiB.
def test_a_split_that_does_not_fit_in_memory_is_refused_before_reading(datasets, monkeypatch):
    """The room is what simlidar.resources reads off the machine (available memory, the cgroup,
    ``ulimit -v``), here made 50 KiB: an address-space limit just above the process's size was
    tried first, and h5py's own allocations while opening the file fail under it at random."""
    import h5py

    import simlidar.resources
    from simlidar.data import load_split
    from simlidar.errors import ResourceError

    monkeypatch.setattr(simlidar.resources, "available_memory", lambda: 50 * 1024)
    reads = []
    real = h5py.Dataset.__getitem__
    monkeypatch.setattr(
        h5py.Dataset, "__getitem__", lambda ds, key: reads.append(ds) or real(ds, key)
    )
    path = datasets[0.1] / "train.h5"
    with pytest.raises(ResourceError) as refused:
        load_split(datasets[0.1])
    assert str(refused.value) == (
        f"{path}: 'delays' (96, 16, 16) float32, 'labels' (96,) int64: 96.8 KiB to hold in "
        "memory, 50.0 KiB available; expected data that fits (a smaller split, or a machine with "
        "more memory)"
    )
    assert not [ds for ds in reads if ds.name in ("/delays", "/labels")]  # nothing read


# 14. A fetched dataset carrying a subfolder (payload/run_me.sh): refused at fetch's verify
# step, nothing installed (it used to install and verify OK).
def test_a_dataset_carrying_a_subfolder_is_not_installed(server, datasets, tmp_path, cli):
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
    result = cli("fetch", f"{url}/{name}.tar.gz", "--sha256", digest, "--out", out)
    assert result.exit_code == 1, result.output
    (line,) = _error_lines(result)
    assert line.startswith("Error: fetch failed at verify: ") and "payload: is a folder" in line
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("kind", ["profile", "sensor", "model", "suite"])
def test_every_content_file_is_read_by_the_one_hardened_reader(tmp_path, cli, kind):
    """Profiles, sensors, model recipes and suites share content.read_toml: a folder, bytes
    that are not UTF-8 and an oversized file each end in one line naming the file and what
    was expected (before, a folder was "file not found" or "expected one of [...]", and suites
    and model recipes had no size limit)."""
    command = {
        "profile": ["generate", "--out", tmp_path / "o", "--profile"],
        "sensor": ["generate", "--out", tmp_path / "o", "--sensor"],
        "model": ["train", "--dataset", tmp_path, "--model"],
        "suite": ["bench", "--out", tmp_path / "o", "--suite"],
    }[kind]
    folder = tmp_path / "folder.toml"
    folder.mkdir()
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'description = "caf\xe9"\n')
    big = tmp_path / "big.toml"
    big.write_text("# pad\n" * 200_000)
    for path, words in [
        (folder, "expected a regular file, got a folder"),
        (latin, "expected UTF-8 text, got byte 0xe9 at offset 18"),
        (big, "expected a file of at most"),
    ]:
        result = cli(*command, path)
        assert result.exit_code in (1, 2) and "Traceback" not in result.output, result.output
        (line,) = [x for x in result.output.splitlines() if "rror" in x]
        assert str(path) in line and words in line, (kind, line)
    assert not (tmp_path / "o").exists()
