"""The speed scripts under benchmark/ run (their figures are for people, not for asserts)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_generation_stages_times_every_stage():
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / "generation_stages.py"), "--samples", "192"],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    lines = done.stdout.splitlines()
    if sys.platform.startswith("linux"):
        assert lines[0] == "shared Embree buffers: on"
    assert "192 samples in" in lines[1]
    stages = {line[:34].strip(): float(line[34:].split()[0]) for line in lines[2:]}
    assert set(stages) == {
        "Embree BVH build + ray queries",
        "other",
        "HDF5 writing",
        "profile and noise",
        "scene building (numpy)",
        "back-face culling",
        "random streams (SeedSequence)",
        "window rays",
        "Embree geometry",
    }
    assert all(us > 0 for name, us in stages.items() if name != "other")


@pytest.mark.parametrize("script", ["generation_speed.py", "generation_stages.py"])
def test_scripts_explain_themselves(script):
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / script), "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "--samples" in done.stdout


def test_ttfs_speed_prints_both_ratios():
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / "ttfs_speed.py"), "--steps", "1"],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    lines = done.stdout.splitlines()[1:]
    assert [line.split()[0] for line in lines] == ["scnn_kitti", "snn_simlidar"]
    for line in lines:
        ratio = float(line.split("ratio ")[1].split()[0])
        assert ratio > 0 and ("target <= 5" in line or "target <= 3" in line)


def test_ttfs_torch_speed_times_both_forms_in_one_run():
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / "ttfs_torch_speed.py"), "--steps", "1"],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    (line,) = done.stdout.splitlines()[1:]
    assert line.startswith("snn_simlidar (batch 60 x 1 x 16 x 16): kernels ")
    kernels, torch_form = (float(line.split(f"{k} ")[1].split()[0]) for k in ("kernels", "form"))
    ratio = float(line.split("ratio ")[1].split()[0])
    assert kernels > 0 and torch_form > 0 and "target <= 20" in line
    assert abs(ratio - torch_form / kernels) <= 0.05 + 0.01 * ratio  # printed to 0.1 ms


def test_generation_workers_compares_the_counts_on_the_same_bytes():
    done = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmark" / "generation_workers.py"),
            *("--samples", "400", "--rounds", "1"),
        ],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    assert "ratio" in done.stdout and "the same bytes for every count: yes" in done.stdout


def test_sweep_speed_prints_frames_per_second_and_the_ratio(tmp_path):
    figures = tmp_path / "sweep.json"
    done = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmark" / "sweep_speed.py"),
            "--frames",
            "16",
            "--samples",
            "1024",
            "--json",
            str(figures),
        ],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    lines = done.stdout.splitlines()
    assert lines[0].startswith("sweep (vlp16, 28928 pulses a frame): ")
    assert "frames/s on one core (target 100" in lines[0]
    assert lines[2].startswith("ratio of pulses/s, sweep over window: ")
    import json

    record = json.loads(figures.read_text())
    assert record["frames"] == 16 and record["frames_per_s"] > 0
    assert record["rays_ratio_sweep_over_window"] == pytest.approx(
        record["sweep_rays_per_s"] / record["window_rays_per_s"], rel=0.01
    )


def _early_objectives():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "early_objectives", ROOT / "benchmark" / "early_objectives.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_early_objectives_reads_the_bound_and_the_targets_by_hand():
    """A bound measured at k = 16, 64, 180 (99 % first at 180): a point at 97.5 % with a
    median of 196 meets the first target (180 + 16) and is within 5 points of the bound read at
    196 (linear between 180 and the next measured k, marked as read between points); a point at
    46 % with a median of 40 is 9 points below the bound there (55 %, halfway from k = 16 to
    64)."""
    eo = _early_objectives()
    curve = ([16, 64, 180, 256], [30.0, 80.0, 99.0, 99.8])
    assert eo.k99(curve) == 180 and eo.k99(([4, 8], [50.0, 98.9])) is None
    assert eo.bound_at(curve, 64) == (80.0, True)
    value, measured = eo.bound_at(curve, 40)
    assert value == pytest.approx(55.0) and not measured  # halfway from 30 to 80
    cell = lambda seed, acc, spikes: {  # noqa: E731
        "seed": seed,
        "test_accuracy": acc,
        "input_spikes": spikes,
        "epochs": 30,
        "early": {"input_spikes_authors_mean": 1.0, "no_decision": 0},
    }
    cells = {
        "far-exp0.1": [cell(0, 0.98, [196] * 5), cell(1, 0.97, [190, 200, 196, 196, 196])],
        "far-exp1": [cell(0, 0.46, [40] * 4)],
    }
    rows = eo.summarise(cells, {"far_first/as_value": curve})
    early, late = rows
    assert early["accuracy"] == pytest.approx(97.5) and early["median"] == 196
    assert early["accuracy_std"] == pytest.approx(0.7071, abs=1e-4)
    assert early["bound"] == pytest.approx(99.0 + 0.8 * 16 / 76) and not early["bound_measured"]
    assert late["gap"] == pytest.approx(55.0 - 46.0)
    goals = eo.targets(rows, "far_first/as_value")
    assert goals["median_limit"] == 196
    assert goals["points_meeting_97_at_limit"] == ["far-exp0.1"]
    assert goals["points_within_5_of_bound"] == ["far-exp0.1"]
    assert goals["points_farther_than_5"] == ["far-exp1"]
