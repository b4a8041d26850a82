"""Dataset profiles: loading, every error path, what each writes, the encoding it hands to
spiking networks, and regeneration from the card."""

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from simlidar.dataset.loaders import spike_threshold
from simlidar.dataset.reader import read_split_info
from simlidar.dataset.schema import SCHEMA
from simlidar.errors import ConfigError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate, generated_name
from simlidar.generator.profiles import DEFAULT_PROFILE, load_profile, profile_names
from simlidar.generator.pulses import noisy_delays, profile_pulses

PAPER = dict(variation=0.05, shift=0.05, missing_delay=0.0, noise_on="all", spikes="all")
PHYSICAL = dict(variation=1.0, shift=0.0, missing_delay=1.0, noise_on="returns", spikes="returns")


def test_shipped_profiles_and_the_default(cli):
    assert {"paper", "physical"} <= set(profile_names())
    assert DEFAULT_PROFILE == "paper"
    for name, values in (("paper", PAPER), ("physical", PHYSICAL)):
        profile = load_profile(name)
        assert profile.name == name and profile.description
        assert {k: getattr(profile, k) for k in values} == values
    listing = cli("profiles")
    assert listing.exit_code == 0 and "paper (default)" in listing.stdout
    shown = json.loads(cli("profiles", "--json").stdout)
    assert shown["default"] == "paper" and {p["name"] for p in shown["profiles"]} >= {
        "paper",
        "physical",
    }


def _write(tmp_path, text, name="mine.toml"):
    path = tmp_path / name
    path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
    return path


GOOD = (
    'description = "x"\nvariation = 0.5\nshift = 0.0\nmissing_delay = 0.0\n'
    'noise_on = "all"\nspikes = "all"\n'
)


@pytest.mark.parametrize(
    "text, expected",
    [
        (GOOD.replace("variation = 0.5", "variation = 0"), "key 'variation': expected a factor"),
        (GOOD.replace("variation = 0.5", "variation = nan"), "key 'variation'"),
        # an integer too large for a float (it used to end in OverflowError's traceback)
        (
            GOOD.replace("variation = 0.5", f"variation = {10**400}"),
            "key 'variation': expected a factor in (0, 1], got 1000",
        ),
        (GOOD.replace("shift = 0.0", f"shift = {10**400}"), "(401 characters)"),
        (GOOD.replace("shift = 0.0", "shift = 1.0"), "key 'shift': expected a value in [0, 1)"),
        (GOOD.replace("missing_delay = 0.0", "missing_delay = 0.5"), "key 'missing_delay'"),
        (GOOD.replace('noise_on = "all"', 'noise_on = "some"'), "key 'noise_on': expected one"),
        (GOOD.replace('spikes = "all"', 'spikes = "returns"'), "key 'spikes': expected 'all'"),
        (GOOD + "colour = 1\n", "key 'colour': expected one of"),
        (GOOD.replace('description = "x"\n', ""), "key 'description' is missing"),
        (GOOD.replace('description = "x"', "description = 3"), "key 'description'"),
        ("variation = [", "not valid TOML"),
        (b"\xff\xfe\x00binary", "expected UTF-8 text, got byte 0xff at offset 0"),
        ("# pad\n" * 20000, "expected a file of at most 65536 bytes, got 120000 bytes"),
    ],
)
def test_a_bad_profile_file_is_one_line_naming_file_and_key(tmp_path, text, expected, cli):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=None) as error:
        load_profile(path)
    assert str(path) in str(error.value) and expected in str(error.value)
    assert "\n" not in str(error.value)
    result = cli("generate", "--profile", path, "--out", tmp_path / "out")
    assert result.exit_code == 2 and expected in result.output
    assert not (tmp_path / "out").exists()  # nothing written


def test_unknown_profile_names_and_file_names(tmp_path, cli):
    result = cli("generate", "--profile", "nonsense", "--out", tmp_path / "out")
    assert result.exit_code == 2
    assert "profile 'nonsense': expected one of" in result.output and "'paper'" in result.output
    missing = cli("generate", "--profile", tmp_path / "absent.toml", "--out", tmp_path / "out")
    assert missing.exit_code == 2 and "file not found" in missing.output
    spaced = _write(tmp_path, GOOD, "My Profile.toml")
    bad_name = cli("generate", "--profile", spaced, "--out", tmp_path / "out")
    assert bad_name.exit_code == 2 and "file name 'My Profile'" in bad_name.output
    assert not (tmp_path / "out").exists()


def test_the_paper_rule_and_the_physical_rule_on_hand_made_pulses():
    clean = np.array([[0.2, 1.0], [0.9, 1.0]], np.float32)  # 1.0: missing return
    u = np.array([[0.5, 0.5], [0.5, 1.0]], np.float32)
    written, noisy = profile_pulses(clean, 0.4, u, 0.0, "all")
    np.testing.assert_allclose(written, [[0.2, 0.0], [0.9, 0.0]])
    np.testing.assert_allclose(noisy, [[0.4, 0.2], [1.0, 0.4]])  # 0.9 + 0.2 clipped at 1
    written, noisy = profile_pulses(clean, 0.4, u, 1.0, "returns")
    assert written is clean
    np.testing.assert_allclose(noisy, [[0.4, 1.0], [1.0, 1.0]])
    # the "coded 0 but noise-free" variant: missing returns stay exactly 0
    assert noisy_delays(
        np.float32([0.2, 0.0]), 0.4, np.float32([0.5, 0.5]), 0.0, "returns"
    ).tolist() == pytest.approx([0.4, 0.0])


def _content_digest(path: Path) -> str:
    digest = hashlib.sha256()
    for split in ("train", "test"):
        with h5py.File(path / f"{split}.h5") as f:
            for name in SCHEMA:
                digest.update(f[name][:].tobytes())
            digest.update(f.attrs["config"].encode())
    return digest.hexdigest()


# Digests of every dataset and the config of 64 / 32-sample datasets (noise 0.2, seed 0)
# written by simlidar before profiles existed (commit 4d53f4f), measured once by this digest.
BEFORE_PROFILES = {
    (): "81930a340bf2d5625078b7d28619318d32061705d590f3decc1144292ed5f6d8",
    (("variation", 0.1), ("shift", 0.05)): (
        "23aa1e2a3be6bb58d2a800ee88672b9bf9c04583c5b8a2136a9f842990fc2ce0"
    ),
}


@pytest.mark.parametrize("options", list(BEFORE_PROFILES))
def test_the_physical_profile_writes_the_records_of_1_0_0(tmp_path, options, cli):
    flags = [a for key, value in options for a in (f"--{key}", value)]
    result = cli(
        "generate",
        "--profile",
        "physical",
        "--train-size",
        64,
        "--test-size",
        32,
        *flags,
        "--out",
        tmp_path,
        "--json",
    )
    assert result.exit_code == 0, result.output
    path = Path(json.loads(result.stdout)["datasets"][0]["path"])
    assert _content_digest(path) == BEFORE_PROFILES[options]
    attrs = read_split_info(path / "train.h5").attrs
    assert attrs["dataset_version"] == "1.0.0" and "profile" not in attrs
    assert path.name.startswith("simlidar-32c-noise0.2-physical") and path.name.endswith("v1.0.0")


# the command line written out as a user types it, each test its own flags (alike in form)
def test_the_default_is_the_paper_profile(tmp_path, cli):
    result = cli(
        "generate",
        "--classes",
        32,
        "--noise",
        0.2,
        "--train-size",
        64,
        "--test-size",
        32,
        "--out",
        tmp_path,
        "--json",
    )
    assert result.exit_code == 0, result.output
    path = Path(json.loads(result.stdout)["datasets"][0]["path"])
    assert path.name == "simlidar-32c-noise0.2-paper-v2.0.0"
    with h5py.File(path / "train.h5") as f:
        attrs = dict(f.attrs)
        delays, clean, tof = f["delays"][:], f["clean_delays"][:], f["tof_ns"][:]
        shift = f["shift"][:]
    assert attrs["profile"] == "paper" and attrs["dataset_version"] == "2.0.0"
    assert attrs["no_return_delay"] == 0.0 and attrs["input_spikes"] == "all"
    assert json.loads(attrs["config"])["profile"]["name"] == "paper"
    assert json.loads(attrs["config"])["variation"] == 0.05
    missing = clean == 0.0
    assert missing.any() and (clean[np.isnan(tof)] == 0.0).all()  # no return is written 0.0
    lost = missing & ~np.isnan(tof)  # a return shifted out of the window is missing too
    assert (shift[lost.any(axis=(1, 2))] != 0).all()
    # noise on every pixel: a missing return reads U(0, 0.2), never exactly 0 everywhere
    assert 0.0 <= delays[missing].min() and delays[missing].max() <= 0.2
    assert delays[missing].std() > 0.05
    assert np.abs(shift).max() <= 0.05 and np.abs(shift).max() > 0.04
    assert (delays >= clean).all() and delays.max() <= 1.0
    card = (path / "README.md").read_text()
    assert "--profile paper" in card and "profile paper" in card.split("---")[1]
    info = cli("info", path)
    assert info.exit_code == 0 and "2.0.0" in info.output


def test_options_override_the_profile_and_the_name_says_so(tmp_path, cli):
    result = cli(
        "generate",
        "--variation",
        0.1,
        "--train-size",
        32,
        "--test-size",
        32,
        "--out",
        tmp_path,
        "--json",
    )
    assert result.exit_code == 0
    assert "--variation 0.1 overrides profile paper's 0.05" in result.stderr
    path = json.loads(result.stdout)["datasets"][0]["path"]
    assert path.endswith("simlidar-32c-noise0.2-paper-var0.1-v2.0.0")
    same = cli(
        "generate",
        "--variation",
        0.05,
        "--train-size",
        32,
        "--test-size",
        32,
        "--out",
        tmp_path / "b",
        "--json",
    )
    assert "overrides" not in same.stderr  # the profile's own value: nothing to say
    assert json.loads(same.stdout)["datasets"][0]["path"].endswith("noise0.2-paper-v2.0.0")
    assert generated_name(
        GeneratorConfig.from_profile(load_profile("physical"), shift_max=0.1, noise=0.5)
    ) == ("simlidar-32c-noise0.5-physical-shift0.1-v1.0.0")


def test_a_profile_file_regenerates_from_its_card(tmp_path, cli):
    path = _write(
        tmp_path, GOOD.replace('noise_on = "all"', 'noise_on = "returns"'), "zero-quiet.toml"
    )
    result = cli(
        "generate",
        "--profile",
        path,
        "--train-size",
        32,
        "--test-size",
        32,
        "--out",
        tmp_path / "a",
        "--json",
    )
    assert result.exit_code == 0, result.output
    first = Path(json.loads(result.stdout)["datasets"][0]["path"])
    assert first.name == "simlidar-32c-noise0.2-zero-quiet-v2.0.0"
    with h5py.File(first / "train.h5") as f:
        clean, delays = f["clean_delays"][:], f["delays"][:]
    assert (delays[clean == 0.0] == 0.0).all()  # noise on returns only
    # a profile that is not shipped: the card gives the Python form, with the profile's values
    card = (first / "README.md").read_text()
    code = card.split("## Regenerate")[1].split("```\n")[1]
    assert "GeneratorConfig.from_dict(" in code and "'zero-quiet'" in code
    from simlidar.scene.recipe import load_catalog

    config = GeneratorConfig.from_dict(eval(code.split("from_dict(", 1)[1].split(")\n")[0]))
    again = generate(config, [config.noise], load_catalog(), tmp_path / "b", progress=False)
    for name in ("train.h5", "test.h5", "README.md", "SHA256SUMS"):
        assert (again[0].path / name).read_bytes() == (first / name).read_bytes(), name


@pytest.mark.parametrize("profile", ["paper", "physical"])
def test_the_card_command_regenerates_a_shipped_profile(tmp_path, profile, cli):
    result = cli(
        "generate",
        "--profile",
        profile,
        "--train-size",
        32,
        "--test-size",
        32,
        "--noise",
        0.33,
        "--shift",
        0.02,
        "--out",
        tmp_path / "a",
        "--json",
    )
    first = Path(json.loads(result.stdout)["datasets"][0]["path"])
    card = (first / "README.md").read_text()
    command = card.split("## Regenerate")[1].split("```\n")[1].strip().split()
    assert command[:4] == ["simlidar", "generate", "--profile", profile]
    again = cli(*command[1:], "--out", tmp_path / "b")
    assert again.exit_code == 0, again.output
    for name in ("train.h5", "test.h5", "README.md", "SHA256SUMS"):
        assert (tmp_path / "b" / first.name / name).read_bytes() == (first / name).read_bytes()


# the command line written out, as in tests/cli/test_cli.py's variation test: each test its
# own flags
def test_the_encoding_follows_the_profile(tmp_path, cli):
    from simlidar.bench.checkpoints import load_checkpoint, save_checkpoint
    from simlidar.bench.early import early_decisions
    from simlidar.bench.train import train
    from simlidar.models.registry import load_recipe

    paths = {}
    for profile in ("paper", "physical"):
        result = cli(
            "generate",
            "--profile",
            profile,
            "--train-size",
            64,
            "--test-size",
            32,
            "--noise",
            0.1,
            "--out",
            tmp_path,
            "--json",
        )
        paths[profile] = Path(json.loads(result.stdout)["datasets"][0]["path"])
    attrs = {p: read_split_info(paths[p] / "train.h5").attrs for p in paths}
    assert spike_threshold(attrs["paper"]) == np.inf and spike_threshold(attrs["physical"]) == 1
    recipe = load_recipe("snn_simlidar")
    spikes = {}
    for profile, path in paths.items():
        result = train(recipe, path, epochs=1, progress=False)
        assert result.model.silent_from == spike_threshold(attrs[profile])
        early = early_decisions(result.model, path)
        spikes[profile] = early["input_spikes_total_mean"]
        saved = save_checkpoint(result, tmp_path / f"{profile}.pt")
        model, _ = load_checkpoint(saved, (1, 16, 16), 32)
        assert model.silent_from == result.model.silent_from
    assert spikes["paper"] == 256.0  # every pixel is an input spike, a missing return at t = 0
    assert spikes["physical"] < 256.0  # the sky and the far road return nothing
