"""What makes a dataset publishable: card, Croissant metadata, checksums, verify, versions.

Attack list of the hostile-directory tests below (each built by the test from a real dataset):
* HDF5 "bombs" (issue 35, item 3): a small split file declaring 20,000,000 samples whose chunks
  were never written (fill values), a contiguous dataset never written, a dataset whose every
  chunk is stored but compressed far beyond what gzip can (scale-offset on a constant), and a
  dataset that is an external or soft link into another file; with the card and SHA256SUMS
  made to agree, so that only the declared sizes are wrong. verify refuses each, the readers
  refuse before allocating, pack writes nothing.
* links and folders in the dataset directory (items 7 and 8): ``notes.txt -> secret`` listed in
  SHA256SUMS, a link to a split file, ``payload/run_me.sh``, an empty folder, a named pipe, a
  ``.DS_Store`` folder; SHA256SUMS or README.md a link to a file outside, for ``simlidar card``
  (which must refuse and leave the target untouched) and ``write_sums`` (which must replace a
  link, never write through it).
* duplicate class names in a split's attributes (item 8).
"""

import json
import shutil

import h5py
import numpy as np
import pytest

from simlidar.any_card import render_card
from simlidar.dataset.reader import read_split_info
from simlidar.errors import DatasetError
from simlidar.release.card import read_front_matter
from simlidar.release.checksums import SUMS, check_sums, read_sums
from simlidar.release.verify import verify


@pytest.fixture
def copy(datasets, tmp_path):
    """A writable copy of the small noise-0.1 dataset."""
    target = tmp_path / datasets[0.1].name
    shutil.copytree(datasets[0.1], target)
    return target


def test_the_card_parses_as_a_hugging_face_dataset_card(datasets):
    from huggingface_hub import DatasetCard

    card = DatasetCard.load(datasets[0.1] / "README.md")
    meta = card.data.to_dict()
    assert meta["license"] == "cc-by-4.0"
    assert meta["configs"][0]["config_name"] == "noise0.1"
    assert {f["split"] for f in meta["configs"][0]["data_files"]} == {"train", "test"}
    splits = {s["name"]: s for s in meta["dataset_info"]["splits"]}
    assert splits["train"]["num_examples"] == 96 and splits["test"]["num_examples"] == 64
    assert splits["train"]["num_bytes"] == (datasets[0.1] / "train.h5").stat().st_size
    features = {f["name"]: f for f in meta["dataset_info"]["features"]}
    assert features["delays"]["array2_d"] == {"shape": [16, 16], "dtype": "float32"}
    assert features["labels"]["dtype"]["class_label"]["names"]["5"] == "open_road/car"
    for section in (
        "## Motivation",
        "## Composition",
        "## Generation process",
        "## Preprocessing",
        "## Uses",
        "### Out-of-scope uses",
        "## Distribution",
        "## Maintenance",
        "## Regenerate",
        "## Versions",
        "## Citation",
    ):
        assert section in card.text, section
    assert "![one example per class (test split)](preview.png)" in card.text
    assert "@article{wang2020temporal" in card.text


def test_the_card_is_made_from_the_files_alone(datasets, copy):
    assert render_card(copy) == (datasets[0.1] / "README.md").read_text()


def test_the_regenerate_command_gives_the_same_bytes(datasets, tmp_path, cli):

    text = (datasets[0.5] / "README.md").read_text()
    command = text.split("## Regenerate")[1].split("```\n")[1].strip()
    assert command.startswith("simlidar generate ")
    args = command.split()[1:] + ["--out", str(tmp_path)]
    assert cli(*args).exit_code == 0
    again = tmp_path / datasets[0.5].name
    for name in ("train.h5", "test.h5", "README.md", "croissant.json", "SHA256SUMS"):
        assert (again / name).read_bytes() == (datasets[0.5] / name).read_bytes(), name


def test_croissant_validates_with_mlcroissant(datasets, caplog):
    import mlcroissant as mlc

    path = datasets[0.1] / "croissant.json"
    dataset = mlc.Dataset(jsonld=path)
    assert dataset.metadata.name == datasets[0.1].name
    assert not any("not standard" in r.getMessage() for r in caplog.records)
    meta = json.loads(path.read_text())
    sums = read_sums(datasets[0.1])
    for obj in meta["distribution"]:
        assert obj["sha256"] == sums[obj["name"]]
    fields = {f["name"] for f in meta["recordSet"][0]["field"]}
    assert {"delays", "labels"} <= fields


def test_checksums_cover_every_file(datasets):
    sums = read_sums(datasets[0.1])
    assert sorted(sums) == ["README.md", "croissant.json", "preview.png", "test.h5", "train.h5"]
    assert check_sums(datasets[0.1]) == []


def test_a_sound_dataset_verifies(datasets):
    assert verify(datasets[0.1]) == []


def _flip_a_byte(path, offset):
    data = bytearray(path.read_bytes())
    data[offset] ^= 0xFF
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(
    "damage, words",
    [
        (
            lambda d: (d / "train.h5").write_bytes((d / "train.h5").read_bytes()[:5000]),
            "train.h5: cannot read as HDF5",
        ),
        (lambda d: _flip_a_byte(d / "test.h5", -2000), "test.h5: sha256 does not match"),
        (lambda d: (d / "preview.png").unlink(), "preview.png: listed in SHA256SUMS but missing"),
        (lambda d: (d / "notes.txt").write_text("x"), "notes.txt: not listed in SHA256SUMS"),
        (lambda d: (d / SUMS).unlink(), "SHA256SUMS: missing"),
        (lambda d: (d / "README.md").write_text("no front matter"), "expected YAML front matter"),
    ],
)
def test_verify_names_each_problem(copy, damage, words):
    damage(copy)
    problems = verify(copy)
    assert any(words in p for p in problems), problems


def test_verify_checks_schema_ranges_and_card(copy):
    with h5py.File(copy / "train.h5", "r+") as f:
        del f.attrs["seed"]
        f["delays"][0, 0, 0] = 1.5
        f["labels"][1] = 99
    card = copy / "README.md"
    card.write_text(card.read_text().replace("num_examples: 64", "num_examples: 65"))
    problems = "\n".join(verify(copy))
    assert "train.h5: attribute 'seed' missing" in problems
    assert "test.h5: 64 samples, the card says 65" in problems
    with h5py.File(copy / "test.h5", "r+") as f:
        f["delays"][0, 0, 0] = -0.5
        f["labels"][0] = 40
    problems = "\n".join(verify(copy))
    assert "test.h5: 'delays' has values outside [0, 1]" in problems
    assert "test.h5: labels outside 0..31" in problems


def test_verify_catches_wrongly_shaped_arrays_and_newer_versions(copy):
    from simlidar.release.checksums import write_sums

    with h5py.File(copy / "train.h5", "r+") as f:
        flat = f["delays"][:].reshape(len(f["delays"]), -1)
        del f["delays"]
        f["delays"] = flat
    with h5py.File(copy / "test.h5", "r+") as f:
        f.attrs["dataset_version"] = "9.0.0"
    write_sums(copy)
    problems = "\n".join(verify(copy))
    assert "train.h5: 'delays' has shape (96, 256), expected (N, H, W)" in problems
    assert "test.h5: dataset version 9.0.0 is newer" in problems
    with pytest.raises(DatasetError, match="'delays' has shape"):
        read_split_info(copy / "train.h5")


def test_verify_refuses_what_is_not_a_dataset(tmp_path):
    with pytest.raises(DatasetError, match="expected a dataset directory"):
        verify(tmp_path / "nothing")
    with pytest.raises(DatasetError, match="no train.h5 or test.h5"):
        verify(tmp_path)


def test_versions_newer_major_refused_older_warned_once(copy):
    from simlidar.dataset import reader as h5module

    with h5py.File(copy / "train.h5", "r+") as f:
        f.attrs["dataset_version"] = "2.0.0"
    with pytest.raises(DatasetError, match=r"dataset version 2.0.0 is newer .* upgrade simlidar"):
        read_split_info(copy / "train.h5")
    with h5py.File(copy / "test.h5", "r+") as f:
        f.attrs["dataset_version"] = "0.9.0"
    h5module._warned.discard(("simlidar-generator", "0.9.0"))
    with pytest.warns(UserWarning, match=r"dataset version 0.9.0, this simlidar writes 1.0.0"):
        read_split_info(copy / "test.h5")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_split_info(copy / "test.h5")  # once only


def test_front_matter_errors_are_named(copy):
    (copy / "README.md").write_text("---\nlicense: [unclosed\n---\n# x\n")
    with pytest.raises(DatasetError, match="README.md: malformed YAML front matter"):
        read_front_matter(copy)
    (copy / "README.md").unlink()
    with pytest.raises(DatasetError, match="README.md: missing"):
        read_front_matter(copy)
    assert np.isfinite(1.0)


def test_an_hdf5_bomb_is_refused_before_anything_is_allocated(
    copy, tmp_path, limited_python, hdf5_bomb
):
    from simlidar.release.archive import pack

    hdf5_bomb(copy, rows=256)
    assert (copy / "train.h5").stat().st_size < 1_000_000  # 20,000,000 samples declared
    problems = verify(copy)
    assert any(
        "'delays' declares (20000000, 16, 16) float32 (19.1 GiB) but stores 0 B in 0 of 78125 "
        "chunks" in p
        for p in problems
    ), problems
    with pytest.raises(DatasetError, match="declares .* but stores 0 B"):
        read_split_info(copy / "train.h5")
    # load_split in a process of its own under a 4 GiB address-space limit: a regression fails
    # here instead of allocating 19.1 GiB in the test process
    script = "import sys; from simlidar.data import load_split; load_split(sys.argv[1])"
    limit = 4 * 2**30
    result = limited_python(["-c", script, copy], limit)
    assert (
        result.stderr.strip()
        .splitlines()[-1]
        .startswith(
            f"simlidar.errors.DatasetError: {copy / 'train.h5'}: 'attempts' declares (20000000,)"
        )
    ), result.stderr
    with pytest.raises(DatasetError, match="declares"):
        pack(copy, tmp_path / "out")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_contiguous_dataset_never_written_is_refused(copy, hdf5_bomb):
    hdf5_bomb(copy, n=2_000_000)  # contiguous: no storage allocated until written
    problems = "\n".join(verify(copy))
    assert "'delays' declares (2000000, 16, 16) float32 (1.9 GiB) but stores 0 B;" in problems


def test_chunks_compressed_beyond_gzip_are_refused(copy, hdf5_bomb):
    hdf5_bomb(copy, rows=65_536, stored=True)  # every chunk stored, one byte each
    problems = "\n".join(verify(copy))
    expected = "'delays' declares (20000000, 16, 16) float32 (19.1 GiB) but stores 306 B in 306 "
    assert f"{expected}of 306 chunks" in problems


@pytest.mark.parametrize("kind", ["external", "soft"])
def test_a_dataset_that_links_elsewhere_is_refused(copy, tmp_path, kind, agreeing):
    other = tmp_path / "other.h5"
    with h5py.File(copy / "train.h5", "r") as f, h5py.File(other, "w") as o:
        o["delays"] = f["delays"][:]
    with h5py.File(copy / "train.h5", "a") as f:
        f["kept"] = f["delays"][:]
        del f["delays"]
        link = h5py.ExternalLink(str(other), "delays") if kind == "external" else None
        f["delays"] = link if link is not None else h5py.SoftLink("/kept")
    agreeing(copy)
    what = "ExternalLink" if kind == "external" else "SoftLink"
    message = f"'delays' is an HDF5 {what}, expected a dataset in the file"
    assert any(message in p for p in verify(copy))
    with pytest.raises(DatasetError, match=message):
        read_split_info(copy / "train.h5")


def test_a_link_listed_in_the_checksums_fails_verify_and_pack(copy, tmp_path):
    from simlidar.release.archive import pack
    from simlidar.release.checksums import write_sums

    secret = tmp_path / "secret"
    secret.write_text("the secret")
    secret.chmod(0o600)
    (copy / "notes.txt").symlink_to(secret)
    sums = copy / SUMS
    digest = __import__("hashlib").sha256(b"the secret").hexdigest()
    sums.write_text(sums.read_text() + f"{digest}  notes.txt\n")  # listed, and it matches
    problems = verify(copy)
    assert problems == [
        f"{copy / 'notes.txt'}: is a link to {secret}, expected a regular file (a dataset "
        "directory holds only its own files, listed in SHA256SUMS)"
    ]
    with pytest.raises(DatasetError, match="notes.txt: is a link"):
        pack(copy, tmp_path / "out")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    with pytest.raises(DatasetError, match="notes.txt: expected a regular file"):
        write_sums(copy, ["notes.txt"])  # never hashed through the link
    write_sums(copy)  # all: the link is not a file of the dataset
    assert "notes.txt" not in read_sums(copy)


def test_a_split_file_that_is_a_link_fails_verify(copy, tmp_path):
    (copy / "test.h5").rename(tmp_path / "test.h5")
    (copy / "test.h5").symlink_to(tmp_path / "test.h5")
    assert any("test.h5: is a link to" in p for p in verify(copy))


def test_a_split_file_that_is_a_link_is_refused_by_info_as_by_verify(copy, tmp_path, cli):
    """Issue 40, item 8: info followed the link verify refuses (one shared check)."""
    from simlidar.data import load_split

    (copy / "test.h5").rename(tmp_path / "test.h5")
    (copy / "test.h5").symlink_to(tmp_path / "test.h5")
    line = (
        f"{copy / 'test.h5'}: is a link to {tmp_path / 'test.h5'}, expected a regular file (a "
        "dataset directory holds only its own files, listed in SHA256SUMS)"
    )
    assert line in verify(copy)
    result = cli("info", copy)
    assert result.exit_code == 1 and result.output.splitlines() == [f"Error: {line}"]
    with pytest.raises(DatasetError, match="test.h5: is a link to"):
        load_split(copy, "test")


@pytest.mark.parametrize(
    "make, kind",
    [
        (lambda d: (d / "payload").mkdir() or (d / "payload" / "run_me.sh").write_text("x"), ""),
        (lambda d: (d / "empty").mkdir(), ""),
        (lambda d: (d / ".DS_Store").mkdir(), ""),
        (lambda d: __import__("os").mkfifo(d / "pipe"), "named pipe"),
    ],
)
def test_anything_but_a_regular_file_in_a_dataset_fails_verify(copy, tmp_path, make, kind):
    from simlidar.release.archive import pack

    make(copy)
    entry = next(p for p in copy.iterdir() if not p.is_file() or p.is_fifo())
    kind = kind or "folder"
    problems = verify(copy)
    assert problems == [
        f"{entry}: is a {kind}, expected a regular file (a dataset directory holds only its "
        "own files, listed in SHA256SUMS)"
    ]
    with pytest.raises(DatasetError, match=f"is a {kind}"):
        pack(copy, tmp_path / "out")


@pytest.mark.parametrize("name", [SUMS, "README.md"])
def test_card_refuses_a_link_and_never_writes_through_it(copy, tmp_path, name, cli):

    target = tmp_path / "elsewhere"
    target.write_bytes((copy / name).read_bytes())
    (copy / name).unlink()
    (copy / name).symlink_to(target)
    before = target.read_bytes()
    result = cli("card", str(copy))
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.stderr.strip() == (
        f"Error: {copy / name}: is not a regular file (a link or a folder); expected the "
        "dataset's own file: remove it and run simlidar card again"
    )
    assert target.read_bytes() == before and (copy / name).is_symlink()


def test_write_sums_replaces_a_link_instead_of_writing_through_it(copy, tmp_path):
    from simlidar.release.checksums import write_sums

    target = tmp_path / "elsewhere"
    target.write_text("not yours\n")
    (copy / SUMS).unlink()
    (copy / SUMS).symlink_to(target)
    write_sums(copy)
    assert target.read_text() == "not yours\n"
    assert not (copy / SUMS).is_symlink() and check_sums(copy) == []
    assert (copy / SUMS).stat().st_mode & 0o777 == 0o666 & ~_umask()


def _umask() -> int:
    import os

    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_duplicate_class_names_are_refused(copy):
    from simlidar.release.checksums import write_sums

    with h5py.File(copy / "train.h5", "a") as f:
        names = [str(n) for n in f.attrs["class_names"]]
        names[9] = names[5]  # two classes named open_road/car
        f.attrs["class_names"] = np.array(names, dtype=h5py.string_dtype())
    write_sums(copy)
    assert any("attribute 'class_names' is" in p and "distinct" in p for p in verify(copy))
    with pytest.raises(DatasetError, match="attribute 'class_names'"):
        read_split_info(copy / "train.h5")
