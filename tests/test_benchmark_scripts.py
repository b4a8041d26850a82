"""The speed scripts under benchmark/ run (their figures are for people, not for asserts)."""

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# the early-information estimate of issue 42 (benchmark/early_bound.py; the folder keeps the
# older name, bound)
ESTIMATE = "benchmark/results/bound"


def run_script(script: str, *args: str, timeout: float | None = None) -> str:
    """What ``benchmark/<script>`` with ``args`` prints (it must exit 0 within ``timeout``)."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / script), *args],
        capture_output=True,
        text=True,
        check=True,
        timeout=timeout,
    )
    return done.stdout


def stage_times(lines: list[str]) -> dict[str, float]:
    """generation_stages.py's table: stage -> microseconds a sample."""
    found = [re.fullmatch(r"  (.+?) +(-?[\d.]+) us/sample +[\d.]+ %", line) for line in lines]
    assert all(found), lines
    return {m[1]: float(m[2]) for m in found}


def test_generation_stages_times_the_receivers_physics_apart():
    """Issue 43, item 5: with a receiver, its beam, weather and waveform work are stages of
    their own, each counted once (a stage inside another is not in the outer one's time)."""
    lines = run_script(
        "generation_stages.py", "--samples", "192", "--profile", "sensor", "--beam-samples", "2",
        "--return-mode", "dual", "--fog", "50", "--rain", "50", "--waveform-bin", "1",
        timeout=300,
    ).splitlines()  # fmt: skip
    assert "192 samples (sensor) in" in lines[1]
    stages = stage_times(lines[2:])
    receiver = {name for name in stages if name.startswith("receiver: ")}
    assert receiver == {
        "receiver: beam sub-rays",
        "receiver: random streams",
        "receiver: materials, power, detection, noise",
        "receiver: fog backscatter table",
        "receiver: rain drops and echoes",
        "receiver: waveform echoes and peaks",
        "receiver: reported returns",
        "receiver: stored waveform",
    }
    assert all(stages[name] > 0 for name in receiver) and stages["other"] >= 0


@pytest.mark.parametrize("cast", ["numpy", "compiled"])
def test_generation_stages_times_every_stage(cast):
    """Issue 43, item 3: every stage of the issue's table is named, the numpy around the cast
    and the draws' visibility checks apart from "other" (which held both)."""
    args = "--samples", "192", *(("--cast", cast) if cast == "compiled" else ())
    lines = run_script("generation_stages.py", *args, timeout=300).splitlines()
    assert lines[0].endswith(f"the cast: {'compiled kernels' if cast == 'compiled' else cast}")
    if sys.platform.startswith("linux"):
        assert lines[0].startswith("shared Embree buffers: on;")
    assert "192 samples (paper) in" in lines[1]  # the users' command's profile
    draws = float(lines[1].split("; ")[1].split()[0])
    assert 1.0 <= draws < 2.0 and lines[1].endswith("draws a sample; CPU time a stage:")
    stages = stage_times(lines[2:])
    assert set(stages) == {
        "Embree BVH build",
        "Embree ray queries",
        "other",
        "HDF5 writing",
        "profile and noise",
        "scene building",
        "back-face culling",
        "random streams",
        "window rays",
        "Embree geometry",
        "preview.png (own process)",
        "card, Croissant, checksums",
        "draws and visibility checks",
        "numpy around the cast",
        "pulses (range to delays)",
    } | ({"exact range (compiled)", "packing vertices and rays (compiled)",
          "template copies (compiled)"} if cast == "compiled" else set())  # fmt: skip
    assert all(us > 0 for name, us in stages.items() if name != "other")


def test_cast_speed_compares_both_forms_and_their_bytes():
    args = "--samples", "192", "--runs", "1", "--rounds", "1"
    lines = run_script("cast_speed.py", *args, timeout=600).splitlines()
    assert "  hits the same to the last bit: True" in lines
    assert "  scenes the same to the last bit: True" in lines
    assert "  draws the same to the last bit: True" in lines
    ratio = next(line for line in lines if line.startswith("  compiled / numpy"))
    assert 0 < float(ratio.split()[-1])
    load = next(line for line in lines if line.startswith("loading the kernels"))
    assert 0 < float(load.split("median ")[1]) < 30
    end = lines[-1].split()
    assert end[0] == "192" and float(end[3]) > 0 and end[4] == "True"


@pytest.mark.parametrize("script", ["generation_speed.py", "generation_stages.py"])
def test_scripts_explain_themselves(script):
    assert "--samples" in run_script(script, "--help")


def test_ttfs_speed_prints_both_ratios():
    lines = run_script("ttfs_speed.py", "--steps", "1", timeout=600).splitlines()[1:]
    assert [line.split()[0] for line in lines] == ["scnn_kitti", "snn_simlidar"]
    for line in lines:
        ratio = float(line.split("ratio ")[1].split()[0])
        assert ratio > 0 and ("target <= 5" in line or "target <= 3" in line)


def test_ttfs_float32_speed_times_every_forward_walk_of_both_networks():
    """One line per kernel call of a training step (2 dense layers; 2 convolutions and 2 dense
    layers), each with both times and their ratio, the same neurons firing both ways, and a
    summary per network whose figures follow from the layers'."""
    lines = run_script("ttfs_float32_speed.py", "--rounds", "1", timeout=600).splitlines()
    heads = [i for i, line in enumerate(lines) if not line.startswith(" ")]
    assert [lines[i].split(",")[0] for i in heads] == ["snn_simlidar", "scnn_kitti"]
    kernels = [line.split("(")[1].split(",")[0] for line in lines if "layer " in line]
    assert kernels == ["forward"] * 2 + ["conv_forward"] * 2 + ["forward"] * 2
    for line in lines:
        if "layer " in line:
            t64, t32 = (float(line.split(f"float{b} ")[1].split()[0]) for b in (64, 32))
            ratio = float(line.split("ratio ")[1].split()[0])
            assert t64 > 0 and t32 > 0 and abs(ratio - t64 / t32) <= 0.01 + 0.05 * ratio
            fired = line.split("firing: ")[1].rstrip(")").split(" / ")
            assert fired[0] == fired[1]
    summaries = [line for line in lines if "the forward walks" in line]
    assert len(summaries) == 2 and all("faster" in line for line in summaries)


def test_the_float32_twins_sum_in_float32():
    """The twins of ttfs_float32_speed are the kernels with float32 sums: on a random dense
    layer they fire the same neurons, at times that differ (float32 rounding) by little."""
    import numpy as np

    from simlidar.models import ttfs, ttfs_kernels

    twins = _script("ttfs_float32_speed").float32_twins()
    rng = np.random.default_rng(0)
    z = np.exp(rng.random((20, 64))).astype(np.float32)
    w = rng.normal(0.05, 0.2, (64, 30)).astype(np.float32)
    ours = ttfs_kernels.forward(z, w, ttfs.MIN_EXCESS, 1)[0]
    theirs = twins["forward"](z, w, ttfs.MIN_EXCESS, 1)[0]
    fired = np.isfinite(ours)
    assert fired.mean() > 0.5 and (np.isfinite(theirs) == fired).all()
    gap = np.abs(ours[fired].astype(np.float64) - theirs[fired])
    assert 0 < gap.max() < 1e-3


def test_ttfs_torch_speed_times_both_forms_in_one_run():
    (line,) = run_script("ttfs_torch_speed.py", "--steps", "1", timeout=600).splitlines()[1:]
    assert line.startswith("snn_simlidar (batch 60 x 1 x 16 x 16): kernels ")
    kernels, torch_form = (float(line.split(f"{k} ")[1].split()[0]) for k in ("kernels", "form"))
    ratio = float(line.split("ratio ")[1].split()[0])
    assert kernels > 0 and torch_form > 0 and "target <= 20" in line
    assert abs(ratio - torch_form / kernels) <= 0.05 + 0.01 * ratio  # printed to 0.1 ms


def test_generation_workers_compares_the_counts_on_the_same_bytes():
    out = run_script("generation_workers.py", "--samples", "400", "--rounds", "1", timeout=300)
    assert "ratio" in out and "the same bytes for every count: yes" in out


def test_sweep_speed_prints_frames_per_second_and_the_ratio(tmp_path):
    figures = tmp_path / "sweep.json"
    args = ("--frames", "16", "--samples", "1024", "--json", str(figures))
    lines = run_script("sweep_speed.py", *args, timeout=300).splitlines()
    assert lines[0].startswith("sweep (vlp16, 28928 pulses a frame): ")
    assert "frames/s on one core (target 100" in lines[0]
    assert lines[2].startswith("ratio of pulses/s, sweep over window: ")
    import json

    record = json.loads(figures.read_text())
    assert record["frames"] == 16 and record["frames_per_s"] > 0
    assert record["rays_ratio_sweep_over_window"] == pytest.approx(
        record["sweep_rays_per_s"] / record["window_rays_per_s"], rel=0.01
    )


def test_motion_speed_times_each_way_and_the_object_filter(tmp_path):
    """benchmark/motion_speed.py at a tiny size: the three ways' figures and ratios, the
    poses at every pulse only where something moves, the nearer of two casts only where the
    object moves, the share of rays the object filter passes and the times with and without
    it, and the sequence's rates."""
    figures = tmp_path / "motion.json"
    args = "--sequences", "33", "--repeats", "1", "--sequence-frames", "4", "--frames", "4"
    args += "--json", str(figures)
    lines = run_script("motion_speed.py", *args, timeout=300).splitlines()
    assert re.fullmatch(
        r"one core: affinity \[\d+\], \d+ thread\(s\) after the casts; .+", lines[0]
    )
    assert any(line.startswith("   33 car ") for line in lines)
    targets = [line for line in lines if line.startswith("  target: ")]
    assert len(targets) == 2 and all("not measurable" in line for line in targets)
    lines_text = "\n".join(lines)
    record = json.loads(figures.read_text())
    every = record["us_a_pulse_all"]
    assert every["standing"] > 0 and every["ego"] > 0 and every["ego and object"] > 0
    for way in ("ego", "ego and object"):
        assert record["ratio_to_standing"][way] == pytest.approx(every[way] / every["standing"])
    stages = record["stages_us_a_pulse"]
    poses, nearest = "poses at every pulse (PlanarMotion)", "nearest of the two casts"
    # standing, a sequence's frames take the ego's pose at their reference times only
    assert stages["standing"].get(poses, 0.0) < 0.05 * stages["ego"][poses]
    assert nearest not in stages["ego"] and stages["ego and object"][nearest] > 0
    kept = record["object_filter"]
    assert 0 < kept["share"] < 0.5  # a car 19 m ahead: a few percent of the rays
    assert kept["with_filter_us_a_pulse"] > 0 and kept["every_ray_us_a_pulse"] > 0
    assert f"rays a frame with an object casts at it: {100 * kept['share']:.2f} %" in lines_text
    assert record["sequence"]["frames"] == 4
    assert all(rate > 0 for rate in record["sequence"]["frames_per_s"].values())


def _script(name: str):
    """The module ``benchmark/<name>.py``, imported (its main is not run)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmark" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_physical_gap_reads_the_committed_cells_of_the_physical_profile():
    """benchmark/ablation/physical_gap.py trains only its two new datasets' cells: the
    physical profile's are the committed ones of sweep_decisions.py, found by their names."""
    gap = _script("ablation/physical_gap")
    dataset = Path("simlidar-32c-noise0.2-physical-v1.0.0")
    for recipe in gap.RECIPES:
        for seed in range(5):
            name = gap.cell_name(dataset.name, 16, seed, recipe)
            cell = json.loads(gap.found_cell(Path("/nonexistent"), name).read_text())
            assert (cell["recipe"], cell["seed"], cell["dataset"]) == (recipe, seed, dataset.name)
            assert cell["architecture"] == {"input_columns": 16}


def test_physical_gap_counts_the_gap_from_the_intervals_lower_end(tmp_path):
    """One network on one dataset: accuracy over seeds, its 95 % interval (Student's t), the
    estimate's best row and its CNN family, and the gap as issue 42 counts it."""
    gap = _script("ablation/physical_gap")
    cells = [{"seed": s, "test_accuracy": a} for s, a in enumerate([0.70, 0.72, 0.74])]
    cnn = {"accuracy": [0.80, 0.82, 0.84]}
    bound = {"row": {"accuracy_mean": 0.9, "best": "cnn/ensemble", "learners": {"cnn": cnn}}}
    row = gap.summarise(cells, bound)
    low = 72.0 - 4.302652729911275 * 2.0 / math.sqrt(3)  # t(0.975, 2) * std / sqrt(n)
    assert row["mean"] == 72.0 and row["std"] == 2.0 and row["ci95"][0] == round(low, 2)
    assert (row["bound"], row["bound_best"]) == (90.0, "cnn/ensemble")
    assert row["cnn_learner_mean"] == 82.0
    assert row["gap"] == round(90.0 - low, 1)
    gap.write(tmp_path, {"physical": {"mlp": {"dataset": "d", **row}}}, "cmd")
    assert "| physical (`d`) | mlp | 3 | 72.00 ± 2.00 [" in (tmp_path / "gap.md").read_text()


def test_the_relu_control_is_the_cnn_shape_variant_with_relu_trained_the_same_way():
    """scnn_variants' ``relu-cnn`` is ``cnn-shape``'s control: the paper's CNN, whose layers
    ``cnn-shape`` copies as TTFS layers, trained under the spiking recipe's protocol (no
    validation rows, fresh noise, its epochs on a cosine schedule, its batch) with its own
    optimiser and rate."""
    from simlidar.models.registry import load_recipe

    variants = _script("ablation/scnn_variants")
    spiking = load_recipe("scnn_simlidar_tuned")
    spiking["training"]["validation"] = 0
    control = variants.relu_control(spiking)
    shape, _ = variants.VARIANTS["cnn-shape"]
    assert control["model"] == "cnn"
    assert (control["architecture"]["conv"], control["architecture"]["dense"]) == (
        shape["conv"],
        shape["dense"],
    )
    protocol = ("validation", "noise_augment", "lr_schedule", "epochs", "batch_size")
    assert all(control["training"][k] == spiking["training"][k] for k in protocol)
    assert (control["training"]["optimizer"], control["training"]["lr"]) == ("adam", 1e-3)
    assert "fire_penalty" not in control["training"]


def test_scnn_variants_summary_reads_its_cells_as_a_file_from_elsewhere(tmp_path):
    """``--summary``: per variant and device the seeds, test and train accuracy over seeds with
    the test's 95 % interval (Student's t), and their gap; a line that is not such a cell is
    a one-line ResultsError naming the file and the line."""
    from simlidar.errors import ResultsError

    variants = _script("ablation/scnn_variants")
    # the spiking CNN's cells, written before cells named their network, and a dense one's
    rows = [{"variant": "tuned", "seed": s, "test_accuracy": a, "train_accuracy": t}
            for s, a, t in ((0, 0.70, 0.90), (1, 0.72, 0.94), (2, 0.74, 0.92))]  # fmt: skip
    rows.append({"recipe": "snn_simlidar_tuned", "variant": "no-return-channel", "seed": 0,
                 "test_accuracy": 0.88, "train_accuracy": 0.99})  # fmt: skip
    path = tmp_path / "cells.jsonl"
    path.write_text("".join(json.dumps({"device": "cpu", **row}) + "\n" for row in rows))
    table = variants.summary(path).splitlines()
    low = 72.0 - 4.302652729911275 * 2.0 / math.sqrt(3)  # t(0.975, 2) * std / sqrt(n)
    assert table[2] == (
        f"| scnn_simlidar_tuned | tuned | cpu | 0, 1, 2 | 72.00 ± 2.00 | [{low:.2f}, "
        f"{144 - low:.2f}] | 92.00 ± 2.00 | +20.00 |"
    )
    assert table[3] == (
        "| snn_simlidar_tuned | no-return-channel | cpu | 0 | 88.00 ± 0.00 | [nan, nan] | "
        "99.00 ± 0.00 | +11.00 |"
    )
    text = path.read_text()
    path.write_text(text + json.dumps({"device": "cpu", **rows[0]}) + "\n")
    with pytest.raises(ResultsError, match="line 5: seed 0 of tuned .scnn_simlidar_tuned, cpu. a"):
        variants.summary(path)  # a seed twice would weigh twice in the mean
    path.write_text(text + '{"variant": "wide", "seed": 0}\n')
    with pytest.raises(ResultsError, match=r"cells.jsonl, line 5: expected a cell of scnn_var"):
        variants.summary(path)
    path.write_text('{"variant": "wide", "device": "cuda", "seed": 0, "test_accuracy": 0.8}\n')
    assert variants.summary(path).splitlines()[2].endswith("| 80.00 ± 0.00 | [nan, nan] | - | - |")


def test_cnn_learner_inputs_changes_the_view_one_way_at_a_time(tmp_path):
    """The ablation's variants: the arrived channel kept or zeroed, and the standardisation;
    its summary reads its cells as a file from elsewhere."""
    import numpy as np

    from simlidar.errors import ResultsError

    inputs = _script("ablation/cnn_learner_inputs")
    assert inputs.VARIANTS["bound"] == (True, "pixel")
    view = np.arange(12, dtype=np.float32).reshape(2, 2, 3)
    assert inputs.masked(view, True) is view
    gone = inputs.masked(view, False)
    assert (gone[:, 1] == 0).all() and np.array_equal(gone[:, 0], view[:, 0])
    assert view[0, 1, 0] == 3  # the view itself unchanged
    path = tmp_path / "cells.jsonl"
    cells = [("bound", 0, 0.88), ("bound", 1, 0.90), ("no-mask", 0, 0.80)]
    path.write_text("".join(json.dumps({"variant": v, "seed": s, "test_accuracy": a}) + "\n"
                            for v, s, a in cells))  # fmt: skip
    table = inputs.summary(path).splitlines()
    low = 89.0 - 12.706204736174698 * math.sqrt(2) / math.sqrt(2)  # t(0.975, 1) std / sqrt(n)
    assert table[2] == f"| bound | 0, 1 | 89.00 ± 1.41 | [{low:.2f}, {178 - low:.2f}] |"
    assert table[3] == "| no-mask | 0 | 80.00 ± 0.00 | [nan, nan] |"
    path.write_text(path.read_text() + json.dumps({"variant": "bound", "seed": 1,
                                                   "test_accuracy": 0.5}) + "\n")  # fmt: skip
    with pytest.raises(ResultsError, match=r"line 4: seed 1 of bound a second time"):
        inputs.summary(path)  # as scnn_variants': a seed twice would weigh twice in the mean
    path.write_text("[1]\n")
    with pytest.raises(ResultsError, match=r"cells.jsonl, line 1: expected a cell of cnn_learne"):
        inputs.summary(path)


def test_the_late_profile_makes_every_pixel_a_spike_and_a_missing_return_the_window_end(
    tmp_path, cli
):
    """The ablation's one change: a missing return is written as 1.0, as physical, and it is an
    input spike there (the no-return threshold of the loaders is inf)."""
    from simlidar.dataset.loaders import load_split, spike_threshold, split_info

    profile = ROOT / "benchmark/ablation/physical_late.toml"
    done = cli("generate", "--profile", profile, "--noise", "0.2", "--train-size", "32",
        "--test-size", "32", "--out", tmp_path)  # fmt: skip
    assert done.exit_code == 0, done.output
    (dataset,) = tmp_path.iterdir()
    assert dataset.name == "simlidar-32c-noise0.2-physical_late-v2.0.0"
    attrs = split_info(dataset, "test").attrs
    assert spike_threshold(attrs) == math.inf and attrs["no_return_delay"] == 1.0
    delays = load_split(dataset, "test")[0]
    assert (delays == 1.0).any() and (delays <= 1.0).all()


def _early_objectives():
    return _script("early_objectives")


# The committed cells above the estimate of benchmark/results/bound, seed by seed: (source,
# variant, dataset, seed). The gated network behind 16 spikes, seed 1 (405 of 600 test samples
# right): with 5 learner seeds the estimate at k = 16 is the wide MLP's ensemble, 404 of 600
# (with 3 it was 68.3 %); the variant's 5 seeds average 65.70 %.
FLASH_ABOVE_THE_ESTIMATE = {
    ("early-objectives", "far-gate16-e30", "simlidar-32c-noise0.1-paper-v2.0.0", 1),
}


def test_every_committed_spiking_cell_is_at_or_below_the_estimate_but_the_known_one():
    """Issues 42 and 61: the early-information estimate (benchmark/results/bound: three learner
    families with the networks' advantages, seed ensembles, the per-sample form; the best of
    the learners tried, not a bound) is at or above every committed cell of a spiking network
    on the flash datasets it was measured on (profiles paper and physical, noise 0.1 and 0.2):
    a gated cell at its gate's k, any other at its own per-sample decision counts; except
    exactly the cells listed above, each of which leads the estimate's best seed ensemble by
    too few test samples for any pattern of right and wrong to make the lead significant (an
    exact McNemar test at 5 %), and whose variant's seeds' mean the estimate holds. A new cell
    above it fails here until it is listed. The gated network behind 16 spikes (66.06 %, up to
    67.50 % a seed) beat the first, published estimate (64.4 %)."""
    import json

    bound = _script("early_bound")
    runs = sorted((ROOT / ESTIMATE / "runs").glob("*.json"))
    results = [json.loads(p.read_text()) for p in runs]
    measured = {(r["dataset"], r["encoding"]["direction"]) for r in results}
    cells = [
        c for c in bound.network_cells()
        if (c["dataset"], c["direction"]) in measured and c["missing"] == "as_value"
    ]  # fmt: skip
    found = bound.cell_bounds(results, cells)
    assert len(found) == len(cells) >= 120  # every one of them has its estimate
    assert {e["source"] for e in found} >= {"early-objectives", "paper", "paper-table", "physical"}
    assert any(e["gate"] == 16 for e in found)
    above = bound.above_the_bound(found)
    assert {(e["source"], e["variant"], e["dataset"], e["seed"]) for e in above} == (
        FLASH_ABOVE_THE_ESTIMATE
    ), [(e["source"], e["variant"], e["seed"], e["accuracy"], e["bound"]) for e in above]
    for e in above:
        assert 1 <= e["lead"] <= 5 and e["mcnemar_p_min"] > 0.05, e
        assert e["seeds_mean"] <= e["bound"], e


def test_a_lead_over_the_estimate_is_read_in_test_samples():
    """early_bound.above_the_bound: a cell one sample above an estimate that is a seed ensemble
    leads by 1 (p at least 1); 6 samples above an ensemble 2 below the estimate, by 8 (p at
    least 2 ** -7: significant if those samples make it); cells at or below are not listed,
    nor a tie that float32's rounding of the cell's accuracy puts a hair above. The largest
    p-value any pattern gives a lead: the two disagreeing on as many samples as their counts
    allow (405 right of 600 against 404: the ensemble alone right on the 195 samples the
    network misses, the network alone on 196)."""
    import numpy as np

    bound = _script("early_bound")
    base = {"source": "s", "dataset": "d", "samples": 600}
    found = [
        {**base, "variant": "a", "seed": 0, "accuracy": 405 / 600, "bound": 404 / 600,
         "ensemble": 404 / 600},
        {**base, "variant": "a", "seed": 1, "accuracy": 390 / 600, "bound": 404 / 600,
         "ensemble": 404 / 600},
        {**base, "variant": "b", "seed": 0, "accuracy": 0.51, "bound": 0.5, "ensemble": 0.4966667},
        {**base, "variant": "c", "seed": 0, "accuracy": 0.5, "bound": 0.5, "ensemble": 0.5},
        {**base, "variant": "c", "seed": 1, "accuracy": float(np.float32(599 / 600)),
         "bound": 599 / 600, "ensemble": 599 / 600},  # a tie, the cell's figure in float32
    ]  # fmt: skip
    above = bound.above_the_bound(found)
    assert [(e["variant"], e["seed"]) for e in above] == [("a", 0), ("b", 0)]
    assert above[0]["lead"] == 1 and above[0]["mcnemar_p_min"] == 1.0
    assert above[0]["seeds_mean"] == pytest.approx(397.5 / 600)
    assert above[1]["lead"] == 8 and above[1]["mcnemar_p_min"] == pytest.approx(2.0**-7)
    from scipy.stats import binomtest

    assert binomtest(8, 8).pvalue == pytest.approx(above[1]["mcnemar_p_min"])
    assert above[0]["mcnemar_p_max"] == pytest.approx(binomtest(196, 391).pvalue)
    # 306 right against 298: the ensemble alone right on the 294 samples the network misses
    assert above[1]["mcnemar_p_max"] == pytest.approx(binomtest(302, 596).pvalue)
    # by hand: 6 of 10 right against 4, so 4 each alone at most, and 6 of 10 discordant samples
    # for the network: P(X >= 6) = 386 / 1024 for X ~ B(10, 1/2), two-sided twice that
    assert bound.mcnemar_p_max(2, 6, 4, 10) == pytest.approx(2 * 386 / 1024)
    assert bound.mcnemar_p_max(0, 6, 6, 10) == 1.0


# The committed cells above the estimate of benchmark/results/bound-scan: the first columns,
# where little has arrived and the learners' estimate is noisy (docs/snn.md, "Deciding
# mid-sweep")
MID_SWEEP_ABOVE_THE_ESTIMATE = {
    ("simlidar-32c-noise0.1-paper-v2.0.0", 6, 2),
    *(("simlidar-32c-noise0.2-physical-v1.0.0", 4, seed) for seed in range(5)),
    ("simlidar-32c-noise0.2-physical-v1.0.0", 6, 2),
}


def test_every_committed_mid_sweep_cell_is_at_or_below_the_estimate_but_the_known_ones():
    """Issue 42, item 3: every committed column-gated cell (benchmark/results/sweep-decisions
    and -scnn) is at or below the early-information estimate for its columns on its scan twin
    (the sensor time it decides at: the best row with as much information or less), seed by
    seed, except exactly the cells listed above (at 4 and 6 columns, 19.8-33.7 % against 19.0,
    31.8 and 32.3 %); and every decision came before the next column fired."""
    import json

    sweep = _script("sweep_decisions")
    folder = ROOT / "benchmark/results/sweep-decisions"
    bound_json = ROOT / "benchmark/results/bound-scan/bound.json"
    cells = sorted((folder / "cells").glob("*.json"))
    # and the spiking CNN's (every column of physical 0.2: 75.33-77.33 % against 80.3 %)
    cells += sorted((ROOT / "benchmark/results/sweep-decisions-scnn/cells").glob("*.json"))
    above, checked, width = set(), 0, 16  # the published datasets' 16 columns
    for path in cells:
        cell = json.loads(path.read_text())
        columns = cell["architecture"]["input_columns"]
        name = cell["dataset"]
        rows = sweep.bound_rows(bound_json, re.sub(r"-v[12]\.0\.0$", "-scan-v3.0.0", name))
        if columns not in rows:
            continue
        checked += 1
        if cell["test_accuracy"] > sweep.bound_for(rows, columns, width)["accuracy_mean"]:
            above.add((name, columns, cell["seed"]))
    assert checked == len(cells) >= 65
    assert above == MID_SWEEP_ABOVE_THE_ESTIMATE
    summary = json.loads((folder / "sweep.json").read_text())
    assert all(r["after_next_firing"] == 0 for rows in summary["points"].values() for r in rows)


def test_the_mid_sweep_cells_above_the_estimate_lead_it_by_less_than_the_test_split_resolves():
    """Issue 42, item 3: the points of the cells above (benchmark/ablation/mid_sweep_exceptions.py,
    benchmark/results/sweep-decisions/exceptions.json) are exactly those of the list above; each
    of their committed cells was trained again to the bit (its right or wrong on every test
    sample scores its committed accuracy); and, recomputed here from those records and the
    estimate's run, the seeds' lead over the estimate's best seed ensemble has a 95 % interval over
    the test samples that holds 0, and no seed's McNemar test finds the network better at
    5 %."""
    import json

    exceptions = _script("ablation/mid_sweep_exceptions")
    from simlidar.bench.bound import unpack

    report = json.loads((ROOT / "benchmark/results/sweep-decisions/exceptions.json").read_text())
    points = {(p["dataset"], p["columns"], p["recipe"]): p for p in report["points"]}
    listed = {(name, columns) for name, columns, _ in MID_SWEEP_ABOVE_THE_ESTIMATE}
    assert {(name, columns) for name, columns, _ in points} == listed
    assert set(exceptions.above_the_bound()) == set(points)
    sweep = _script("sweep_decisions")
    for key, point in points.items():
        folder = ROOT / "benchmark/results" / sweep.COMMITTED[key[2]] / "cells"
        for cell in point["cells"]:
            committed = json.loads(
                (folder / sweep.cell_name(key[0], key[1], cell["seed"], key[2])).read_text()
            )
            right = unpack(cell["correct"], (1, cell["samples"]))[0]
            assert float(right.mean()) == pytest.approx(committed["test_accuracy"], abs=1e-6)
        assert [c["seed"] for c in point["cells"]] == exceptions.seeds_of(*key)
        rows = sweep.bound_rows(exceptions.BOUND, exceptions.scan_name(key[0]))
        row = exceptions.bound_for(rows, key[1], exceptions.WIDTH)
        found = exceptions.compare(point["cells"], row, point["cells"][0]["samples"])
        assert found == point["comparison"]  # the committed figures, recomputed
        low, high = found["difference_ci95"]
        assert low < 0 < high
        better = [s for s in found["seeds"] if s["only_network"] > s["only_bound"]]
        assert all(s["mcnemar_p"] > 0.05 for s in better), found["seeds"]


def test_early_objectives_reads_the_estimate_and_the_targets_by_hand():
    """An estimate measured at k = 16, 64, 180 (99 % first at 180): a point at 97.5 % with a
    median of 196 meets the first target (180 + 16) and is within 5 points of the estimate read
    at 196 (linear between 180 and the next measured k, marked as read between points); a
    point at 46 % with a median of 40 is 9 points below the estimate there (55 %, halfway from
    k = 16 to 64)."""
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
        "far-exp0.03": [
            cell(s, a, [190] * 5) for s, a in enumerate([0.98, 0.975, 0.98, 0.975, 0.98])
        ],
    }
    rows = eo.summarise(cells, {"far_first/as_value": curve})
    early, late, steady = rows
    assert early["accuracy"] == pytest.approx(97.5) and early["median"] == 196
    assert early["accuracy_std"] == pytest.approx(0.7071, abs=1e-4)
    # 95 % interval of two seeds: t(0.975, 1) = 12.706 times 0.7071 / sqrt(2)
    assert early["accuracy_ci95"] == pytest.approx([97.5 - 6.353, 97.5 + 6.353], abs=1e-3)
    assert early["bound"] == pytest.approx(99.0 + 0.8 * 16 / 76) and not early["bound_measured"]
    assert late["gap"] == pytest.approx(55.0 - 46.0) and late["accuracy_ci95"] is None
    # five seeds: mean 97.8, std 0.2739, t(0.975, 4) = 2.776: lower end 97.46
    assert steady["accuracy_ci95"][0] == pytest.approx(97.8 - 2.776 * 0.2739 / 5**0.5, abs=1e-3)
    goals = eo.targets(rows, "far_first/as_value")
    assert goals["median_limit"] == 196
    # issue 42: a point meets a target by its interval's lower end: two seeds at 98 and 97 % do
    # not (91.1 %), five between 97.5 and 98 % do
    assert goals["points_meeting_97_at_limit"] == ["far-exp0.03"]
    assert goals["points_within_5_of_bound"] == ["far-exp0.03"]
    assert goals["points_farther_than_5"] == ["far-exp0.1", "far-exp1"]


def test_sweep_decisions_reads_each_decision_on_the_sensors_clock(tmp_path, cli):
    """A column-gated network decides when the last pulse of its first C columns left (the
    scan twin's emission) plus its own latency; the estimate's row for C stands beside it, and a
    target counts a point by its interval's lower end."""
    import json

    import h5py
    import numpy as np

    sweep = _script("sweep_decisions")
    small = ["--train-size", "64", "--test-size", "32", "--profile", "paper", "--noise", "0.1"]
    paths = {}
    for timing in ("flash", "scan"):
        done = cli("generate", *small, "--timing", timing, "--out", tmp_path, "--json")
        assert done.exit_code == 0, done.output
        paths[timing] = Path(json.loads(done.stdout)["datasets"][0]["path"])
    with h5py.File(paths["scan"] / "test.h5") as f:
        emission = f["emission_ns"][:]
    fired, after = sweep.firing_times(paths["scan"], 3)
    assert np.array_equal(fired, emission[:, :, :3].max(axis=(1, 2)))
    assert np.array_equal(after, emission[:, :, 3].min(axis=1)) and (after > fired + 5e5).all()
    assert sweep.firing_times(paths["scan"], 16)[1] is None
    t_out = [250.0] * 31 + [None]  # one sample undecided
    cells = [
        {"seed": s, "test_accuracy": a, "decision_time_ns": t_out, "input_spikes": [48] * 32}
        for s, a in enumerate([0.80, 0.82, 0.81, 0.80, 0.82])
    ]
    times, late = sweep.sensor_times(cells[0], fired, after)
    assert late == 0 and np.isnan(times[-1])
    assert times[:-1] == pytest.approx((fired[:-1] + 250.0) / 1000.0)
    bound = {3: {"accuracy_mean": 0.84, "time_us_median": 1200.0, "columns": 3}}
    row = sweep.summarise(cells, paths["scan"], 3, 16, bound)
    assert row["undecided"] == 5 and row["decision_us_median"] == pytest.approx(
        np.median((fired[:-1] + 250.0) / 1000.0)
    )
    low = row["accuracy_ci95"][0]  # mean 81, std 1, t(0.975, 4) = 2.776: 79.76
    assert low == pytest.approx(81.0 - 2.776 * 1.0 / 5**0.5, abs=1e-3)
    assert row["gap"] == pytest.approx(84.0 - low) and not row["every_column"]
    goals = sweep.targets({"paper:0.1": [row], "physical:0.2": [{**row, "every_column": True}]})
    assert [g["met_by_columns"] for g in goals] == [[], ["3 (hidden 400)"]]  # 4.2; 5 allowed
    # the best row with as much information or less: fewer columns, and with every column
    # the every-spike row
    bound[2] = {"accuracy_mean": 0.85, "time_us_median": 600.0, "columns": 2}
    bound[16] = {"accuracy_mean": 0.84, "time_us_median": 9436.0, "columns": 16}
    bound["all"] = {"accuracy_mean": 0.86, "k": None}
    assert sweep.bound_for(bound, 16, 16)["accuracy_mean"] == 0.86
    assert sweep.bound_for(bound, 3, 16)["accuracy_mean"] == 0.85
    assert sweep.bound_for(bound, 2, 16)["accuracy_mean"] == 0.85
    assert sweep.bound_for(bound, 5, 16) is None  # no row of its own
    assert goals[0]["closest"]["gap"] == pytest.approx(84.0 - low)
    fewer = sweep.targets({"physical:0.2": [{**row, "every_column": True, "seeds": [0, 1]}]})
    assert fewer[0]["met_by_columns"] == [] and fewer[0]["closest"] is None  # 5 seeds a point


@pytest.mark.parametrize(
    "args, words",
    [
        (["--ks", "abc"], "argument --ks: 'abc': expected comma-separated integers >= 1"),
        (["--ks", "0"], "argument --ks: '0': expected comma-separated integers >= 1"),
        (["--ks", "4,-5"], "argument --ks: '4,-5': expected comma-separated integers >= 1"),
        (["--hidden", "0"], "argument --hidden: '0': expected comma-separated integers in"),
        (["--hidden", "100000000"], "argument --hidden: '100000000': expected"),
        (["--encodings", "nonsense"], "argument --encodings: 'nonsense': expected"),
        (["--encodings", "near_first/own_channel"], "'near_first/own_channel': expected"),
        (["--threads", "0"], "argument --threads: '0': expected an integer in [1, 1024]"),
        (["missing-dataset"], "missing-dataset: expected a dataset directory with train.h5"),
        ([], "no datasets given and no runs under"),
    ],
)
def test_early_bound_refuses_a_bad_argument_in_one_line_writing_nothing(args, words, tmp_path):
    """Each used to be a traceback (or, for --ks 0 and -5, a run); nothing is written, and the
    default --out is the working folder's early-bound/, never the repository's results."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / "early_bound.py"), *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode in (1, 2) and "Traceback" not in done.stderr, done.stderr
    (line,) = [x for x in done.stderr.splitlines() if "error: " in x]
    assert words in line, line
    assert not any(tmp_path.iterdir())


def test_early_bound_adds_the_families_a_run_lacks(datasets, tmp_path):
    """A rerun with more ``--learners`` trains only the families a present run lacks, at its
    own seeds and k, and takes every row's estimate again over all of them; the present
    families' figures are kept as they were."""
    dataset = str(datasets[0.1])
    common = ["--ks", "4", "--seeds", "0", "--encodings", "near_first/as_value"]
    first = run_script("early_bound.py", dataset, *common, "--learners", "mlp",
                       "--out", str(tmp_path), timeout=600)  # fmt: skip
    assert "adding" not in first
    (path,) = (tmp_path / "runs").glob("*.json")
    before = json.loads(path.read_text())
    again = run_script("early_bound.py", dataset, "--ks", "8", "--seeds", "1,2", "--encodings",
                       "near_first/as_value", "--learners", "mlp,cnn", "--out", str(tmp_path),
                       timeout=600)  # fmt: skip
    assert "adding the families ['cnn']" in again
    after = json.loads(path.read_text())
    assert set(after["learner"]) == {"mlp", "cnn"} and after["seeds"] == [0]
    assert [r["k"] for r in after["rows"]] == [4, None]
    for old, new in zip(before["rows"], after["rows"]):
        assert new["learners"]["mlp"] == old["learners"]["mlp"]
        both = new["learners"]
        assert new["accuracy_mean"] == max(
            max(f["accuracy_mean"], f["ensemble"]) for f in both.values()
        )


def test_early_bound_takes_a_run_to_more_seeds_and_refuses_one_that_does_not_reproduce(
    datasets, tmp_path
):
    """More ``--seeds`` than a present run of several families has (all of its own among them)
    train it again with all of them at its own k: its seed keeps its figures and the new one
    joins; a present run whose figures the same seed does not give again is refused in one
    line, and its file is left as it was."""
    dataset = str(datasets[0.1])
    common = ["--ks", "4", "--encodings", "near_first/as_value", "--learners", "mlp"]
    run_script("early_bound.py", dataset, *common, "--seeds", "0", "--out", str(tmp_path),
               timeout=600)  # fmt: skip
    (path,) = (tmp_path / "runs").glob("*.json")
    before = json.loads(path.read_text())
    again = run_script("early_bound.py", dataset, "--ks", "8", "--seeds", "0,1", "--encodings",
                       "near_first/as_value", "--learners", "mlp", "--out", str(tmp_path),
                       timeout=600)  # fmt: skip
    assert "trained again with seeds [0, 1]" in again
    after = json.loads(path.read_text())
    assert after["seeds"] == [0, 1] and [r["k"] for r in after["rows"]] == [4, None]
    for old, new in zip(before["rows"], after["rows"]):
        assert new["learners"]["mlp"]["accuracy"][0] == old["learners"]["mlp"]["accuracy"][0]
        assert len(new["learners"]["mlp"]["accuracy"]) == 2
    tampered = dict(before)
    tampered["rows"][0]["learners"]["mlp"]["accuracy"] = [0.123]
    path.write_text(json.dumps(tampered))
    written = path.read_bytes()
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark/early_bound.py"), dataset, *common, "--seeds",
         "0,1", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "of mlp at k = 4 scored [0.123]" in done.stderr and "nothing written" in done.stderr
    assert path.read_bytes() == written


BAD_ARGUMENTS = [
    ("early_objectives.py", ["--variants", "near,nonsense"], "argument --variants: 'nonsense'"),
    ("early_objectives.py", ["--seeds", "0,-1"], "argument --seeds: '0,-1': expected"),
    ("early_objectives.py", ["--noise", "nan"], "argument --noise: 'nan': expected a number"),
    ("early_objectives.py", ["--jobs", "0"], "argument --jobs: '0': expected an integer in"),
    ("early_objectives.py", ["--dataset", "missing-dataset"], "missing-dataset: expected a dat"),
    ("early_objectives.py", ["--recipe", "nosuch"], "model recipe 'nosuch': expected one of"),
    ("early_tradeoff.py", ["--penalties", "0,-1"], "argument --penalties: '0,-1': expected"),
    ("early_tradeoff.py", ["--epochs", "0"], "argument --epochs: '0': expected an integer in"),
    ("early_tradeoff.py", ["--noise", "0.15"], "argument --noise: invalid choice: 0.15"),
    ("generation_scale.py", ["--samples", "100"], "argument --samples: '100': expected an int"),
    ("generation_scale.py", ["--workers", "0"], "argument --workers: '0': expected an integer"),
    ("generation_scale.py", ["--out", "missing"], "--out 'missing': expected an existing folder"),
    ("generation_speed.py", ["--samples", "abc"], "argument --samples: 'abc': expected"),
    ("generation_speed.py", ["--memory", "0"], "argument --memory: '0': expected comma-sep"),
    ("generation_speed.py", ["--json", "no/x.json"], "--json: 'no/x.json': expected a file in"),
    ("generation_stages.py", ["--samples", "0"], "argument --samples: '0': expected an integer"),
    ("generation_workers.py", ["--workers", "1"], "argument --workers: '1': expected an integ"),
    ("generation_workers.py", ["--rounds", "0"], "argument --rounds: '0': expected an integer"),
    ("paper_table.py", ["--seeds", "x"], "argument --seeds: 'x': expected comma-separated"),
    ("paper_table.py", ["--epochs", "cnn=0"], "argument --epochs: 'cnn=0': expected RECIPE=N"),
    ("paper_table.py", ["--recipes", "nosuch"], "model recipe 'nosuch': expected one of"),
    ("scan_timing.py", ["--noise", "2"], "argument --noise: '2': expected a number in [0, 1]"),
    ("scan_timing.py", ["--penalties", "inf"], "argument --penalties: 'inf': expected"),
    ("scan_timing.py", ["--profile", "nosuch"], "profile 'nosuch': expected one of"),
    ("scan_timing.py", ["--picture", "no/x.png"], "--picture: 'no/x.png': expected a file in"),
    ("scene_variation.py", ["--factors", "1,0"], "variation=0.0: expected a factor in (0, 1]"),
    ("scene_variation.py", ["--train-size", "5"], "argument --train-size: '5': expected an"),
    ("scene_variation.py", ["--models", "nosuch"], "model recipe 'nosuch': expected one of"),
    ("sweep_decisions.py", ["--datasets", "paper:0.3"], "'paper:0.3': expected profile:noise"),
    ("sweep_decisions.py", ["--datasets", "lidar:0.1"], "'lidar:0.1': expected profile:noise"),
    ("sweep_decisions.py", ["--columns", "17"], "argument --columns: '17': expected comma-sep"),
    ("sweep_decisions.py", ["--seeds", "x"], "argument --seeds: 'x': expected comma-separated"),
    ("motion_speed.py", ["--repeats", "0"], "argument --repeats: '0': expected an integer in"),
    ("motion_speed.py", ["--sequences", "1,x"], "argument --sequences: '1,x': expected comma"),
    ("motion_speed.py", ["--ego-speed", "nan"], "argument --ego-speed: 'nan': expected a num"),
    ("motion_speed.py", ["--sequence-speed", "10"], "ego_speed_mps=10.0 and the objects' motion"),
    ("motion_speed.py", ["--json", "no/x.json"], "--json: 'no/x.json': expected a file in"),
    ("motion_speed.py", ["--frames", "0"], "argument --frames: '0': expected an integer in"),
    ("sweep_speed.py", ["--frames", "0"], "argument --frames: '0': expected an integer in"),
    ("stream_speed.py", ["--streams", "2"], "argument --streams: '2': expected an integer in"),
    ("stream_speed.py", ["--json", "no/x.json"], "--json: 'no/x.json': expected a file in"),
    ("stream_bench.py", ["/nonexistent/s"], "/nonexistent/s"),
    ("stream_bench.py", ["/x", "--seeds", "x"], "argument --seeds: 'x': expected comma-separ"),
    ("stream_bench.py", ["/x", "--validation", "0.9"], "argument --validation: '0.9': expect"),
    ("stream_bench.py", ["/x", "--models", "nosuch"], "model recipe 'nosuch'"),
    ("stream_bench.py", ["/x", "--no-train"], "no cells to report"),
    ("stream_estimate.py", ["/nonexistent/s"], "/nonexistent/s"),
    ("stream_estimate.py", ["/x", "--families", "svm"], "argument --families: 'svm': expected"),
    ("stream_figure.py", ["/nonexistent/s", "--out", "no/x.png"], "'no/x.png': expected a fi"),
    ("sweep_speed.py", ["--sensor", "nosuch"], "sensor 'nosuch': expected one of"),
    ("ttfs_speed.py", ["--steps", "0"], "argument --steps: '0': expected an integer in"),
    ("ttfs_speed.py", ["--threads", "-2"], "argument --threads: '-2': expected an integer in"),
    ("ttfs_speed.py", ["--device", "tpu"], "--device 'tpu': expected one of ['auto', 'cpu',"),
    ("torch_form_cells.py", ["/nonexistent/x", "--device", "cpu"], "expected a dataset dire"),
    ("ttfs_float32.py", ["/nonexistent/x"], "/nonexistent/x: expected a dataset directory"),
    ("ttfs_float32.py", ["x", "--recipe", "cnn"], "argument --recipe: invalid choice: 'cnn'"),
    ("ttfs_float32_speed.py", ["--rounds", "0"], "argument --rounds: '0': expected an integer"),
    ("ttfs_torch_speed.py", ["--steps", "x"], "argument --steps: 'x': expected an integer in"),
    ("ttfs_torch_speed.py", ["--model", "cnn"], "argument --model: invalid choice: 'cnn'"),
    ("ablation/scnn_variants.py", ["x", "--variants", "nosuch"], "'nosuch': expected comma-s"),
    ("ablation/scnn_variants.py", ["/nonexistent/x"], "/nonexistent/x: expected a dataset dir"),
    ("ablation/scnn_variants.py", [], "expected a dataset directory to train on (or --summ"),
    ("ablation/cnn_learner_inputs.py", ["x", "--variants", "mask"], "'mask': expected comma-"),
    ("ablation/cnn_learner_inputs.py", ["/nonexistent/x"], "/nonexistent/x: expected a datase"),
    ("ablation/cnn_learner_inputs.py", [], "expected a dataset directory to train on (or --su"),
    ("ablation/physical_gap.py", ["--data", "/nonexistent/g", "--seeds", "x"], "'x': expected"),
    ("ablation/physical_gap.py", ["--data", "/nonexistent/g", "--noise", "1"], "'1': expected"),
    ("fog_check.py", ["--samples", "5"], "argument --samples: '5': expected an integer in"),
    ("rain_check.py", ["--samples", "x"], "argument --samples: 'x': expected an integer in"),
    ("receiver_speed.py", ["--repeats", "0"], "argument --repeats: '0': expected an integer"),
    ("weather.py", ["--data", "/nonexistent/w", "--visibilities", "0"], "'0': expected a visi"),
    ("weather.py", ["--data", "/nonexistent/w", "--models", "nosuch"], "model recipe 'nosuch'"),
    ("weather.py", ["--data", "/nonexistent/w", "--rains", "600"], "'600': expected a rain rate"),
    ("weather.py", ["--data", "/x", "--doc", "/nonexistent/d.md"], "'/nonexistent/d.md': expec"),
    (
        "weather.py",
        ["--data", "/x", "--no-bound", "--doc", str(ROOT / "README.md")],
        "--doc with --no-bound: expected the estimate",
    ),  # fmt: skip
    (
        "weather.py",
        ["--data", "/x", "--no-train", "--doc", str(ROOT / "README.md")],
        "README.md: expected one line <!-- weather-above-the-estimate:start -->",
    ),  # fmt: skip
    ("weather.py", ["--data", "/x", "--no-train"], "out/cells: expected cells of ['snn_simlid"),
]
# where a script writes by default (the repository's benchmark/results, or --out required):
# the bad runs are sent to tmp_path / "out", which must not be made
WRITES = {
    "ablation/cnn_learner_inputs.py",
    "ablation/physical_gap.py",
    "ablation/scnn_variants.py",
    "fog_check.py",
    "rain_check.py",
    "weather.py",
    "early_objectives.py",
    "early_tradeoff.py",
    "paper_table.py",
    "scan_timing.py",
    "scene_variation.py",
    "sweep_decisions.py",
    "stream_bench.py",
    "stream_estimate.py",
}


@pytest.mark.parametrize(
    "script, args, words", BAD_ARGUMENTS, ids=[f"{s}{' '.join(a)}" for s, a, _ in BAD_ARGUMENTS]
)
def test_benchmark_scripts_refuse_a_bad_argument_in_one_line_writing_nothing(
    script, args, words, tmp_path
):
    """The CLI's rule for every script that takes arguments: one line naming the value, exit
    code 1 or 2, no traceback, nothing written (each used to be a traceback, a run on
    nonsense, or a traceback after the work)."""
    out = ["--out", str(tmp_path / "out")] if script in WRITES else []
    extra = ["--picture", ""] if script == "scan_timing.py" and "--picture" not in args else []
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmark" / script), *args, *out, *extra],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode in (1, 2) and "Traceback" not in done.stderr, done.stderr
    (line,) = [x for x in done.stderr.splitlines() if "error: " in x]
    assert words in line, line
    assert not any(tmp_path.iterdir())


def test_fog_check_keeps_points_lost_within_half_of_the_chamber_fit():
    """Issue 41's fog check: the VLP-16 receiver's maximum range in fog (reflectance 0.1 and
    0.8, alpha 0.05 to 0.2 per m) within 0.5 to 1.5 times the range Seeing Through Fog's model,
    fitted to fog-chamber measurements of an HDL-64E S3D, gives (measured: 0.66 to 1.34); the
    fit by hand at alpha 0.1, reflectance 0.8: ln(1.25 / 0.04) / 0.2 = 17.2 m."""
    fog = _script("fog_check")
    assert fog.stf_range_m(0.8, 0.1) == pytest.approx(math.log(1.25 / 0.04) / 0.2)
    rows = fog.ranges()
    assert len(rows) == 8 and all(0.5 <= r["ratio"] <= 1.5 for r in rows)
    committed = json.loads((ROOT / "benchmark/results/fog/fog.json").read_text())
    assert [round(r["ratio"], 6) for r in committed["ranges"]] == [
        round(r["ratio"], 6) for r in rows
    ]


def test_rain_check_keeps_the_extinction_within_a_tenth_of_ulbrich_and_atlas():
    """Issue 41's rain check: the generator's rain extinction (Mie since 5.0.0) within 10 % of
    Ulbrich & Atlas's fit (1.45 R^0.64 dB/km) at every rate of the check (measured: 1.04 to
    1.07, also beyond
    the fit's 20 mm/h), the committed table as the script computes it, and the committed
    dataset rows: returns lost and the drops' returns rise with the rate."""
    rain = _script("rain_check")
    rows = rain.extinction()
    assert [r["rate_mm_h"] for r in rows] == [5.0, 10.0, 25.0, 50.0, 100.0, 200.0]
    assert all(0.9 <= r["ratio"] <= 1.1 for r in rows)
    committed = json.loads((ROOT / "benchmark/results/rain/rain.json").read_text())
    assert committed["extinction"] == json.loads(json.dumps(rows))
    lost = [r["lost_percent"] for r in committed["dataset"]]
    drops = [r["weather_returns_percent"] for r in committed["dataset"]]
    assert lost == sorted(lost) and drops == sorted(drops) and lost[0] == 0.0
    assert drops[0] < 0.01  # clear air: the detector's false alarms alone (1 in 10,000 pulses)


def test_weather_scores_models_trained_in_clear_air_on_every_weather(tmp_path):
    """benchmark/weather.py at a tiny size: the clear-air, fog and rain datasets share their
    scenes (same labels), the mixed train split holds row i of weather i mod 3, a model trained
    in clear air or on mixed weather is scored on every test split (its clear-air score is its
    training run's own), the summary's interval is Student's t over seeds, and a cell that
    lacks a weather is trained again and must keep the scores it had."""
    weather = _script("weather")
    out = tmp_path / "out"
    args = ["--data", str(tmp_path / "data"), "--train-size", "64", "--test-size", "32",
            "--visibilities", "50", "--rains", "100", "--models", "cnn", "--seeds", "0,1",
            "--no-bound", "--jobs", "1", "--out", str(out)]  # fmt: skip
    assert weather.main(args) == 0
    result = json.loads((out / "weather.json").read_text())
    names = result["datasets"]
    assert names["clear"].endswith("-sensor-v5.0.0") and "-fog50.0-" in names["50"]
    assert names["rain100"].endswith("-sensor-rain100.0-v5.0.0")
    assert list(result["points"]) == ["cnn", "cnn (mixed)"]
    for model, middle in (("cnn", ""), ("cnn (mixed)", "mixed__")):
        rows = result["points"][model]
        assert [r["weather"] for r in rows] == ["clear", "50", "rain100"]
        cells = [json.loads((out / f"cells/cnn__{middle}seed{s}.json").read_text()) for s in (0, 1)]
        for row in rows:
            accs = [100 * c["test_accuracy"][row["weather"]] for c in cells]
            assert row["accuracy"] == pytest.approx(sum(accs) / 2)
            assert row["accuracy_ci95"] == pytest.approx(
                [row["accuracy"] - 12.706 * row["accuracy_std"] / 2 ** 0.5,
                 row["accuracy"] + 12.706 * row["accuracy_std"] / 2 ** 0.5], abs=1e-2)  # fmt: skip
    import h5py

    data = tmp_path / "data"
    (mixed,) = data.glob("*-mixed-50-rain100")
    assert json.loads((mixed / "mixed.json").read_text())["weathers"] == names
    with h5py.File(mixed / "train.h5") as f:
        delays, labels = f["delays"][:], f["labels"][:]
    for k, name in enumerate(names.values()):
        with h5py.File(data / name / "train.h5") as f:
            assert (f["labels"][:] == labels).all()  # the same scenes in every weather
            assert (f["delays"][k::3] == delays[k::3]).all()
    assert not (delays == h5py.File(data / names["clear"] / "train.h5")["delays"][:]).all()
    # a cell without a weather is trained again; a score that changes stops the run
    path = out / "cells/cnn__seed0.json"
    cell = json.loads(path.read_text())
    kept = kept_clear = dict(cell["test_accuracy"])
    del cell["test_accuracy"]["rain100"]
    path.write_text(json.dumps(cell))
    assert weather.main(args) == 0
    assert json.loads(path.read_text())["test_accuracy"] == kept
    cell["test_accuracy"]["50"] = 2.0  # a score no run can give
    path.write_text(json.dumps(cell))
    with pytest.raises(SystemExit, match="trained again, its scores changed"):
        weather.main(args)
    assert json.loads(path.read_text())["test_accuracy"]["50"] == 2.0  # nothing overwritten
    # a cell trained on other data (another mixture) is trained again, without the check
    mixed = out / "cells/cnn__mixed__seed0.json"
    cell = json.loads(mixed.read_text())
    kept = dict(cell["test_accuracy"])
    cell["trained_on"], cell["test_accuracy"]["50"] = "another-mixture", 2.0
    mixed.write_text(json.dumps(cell))
    path.write_text(json.dumps(json.loads(path.read_text()) | {"test_accuracy": kept_clear}))
    assert weather.main(args) == 0
    assert json.loads(mixed.read_text())["test_accuracy"] == kept
    assert (out / "weather.png").stat().st_size > 0
    assert "| cnn (mixed) |" in (out / "weather.md").read_text()
    # --no-train writes the same reports from the cells there are, making no dataset
    made = {p: p.read_bytes() for p in out.glob("weather.*")}
    shutil.rmtree(tmp_path / "data")
    assert weather.main([*args, "--no-train"]) == 0
    assert {p: p.read_bytes() for p in out.glob("weather.*")} == made
    assert not (tmp_path / "data").exists()


def _weather_cells(folder: Path) -> dict[str, list[dict]]:
    """The committed weather cells by row name ("cnn", "cnn (mixed)", ...), by seed."""
    cells = {}
    for path in sorted((folder / "cells").glob("*.json")):
        cell = json.loads(path.read_text())
        stem, *middle, _ = path.name.split("__")
        cells.setdefault(stem + "".join(f" ({m})" for m in middle), []).append(cell)
    return cells


def test_the_committed_weather_table_recomputes_from_its_cells():
    """benchmark/results/weather: every mean of weather.json is its cells' (5 seeds a model,
    trained in clear air and on mixed weather), the estimate is each weather's every-spike row
    of the estimate's runs (with its best family's seed spread), and no model's mean is above
    the estimate of the weather it is tested in."""
    weather_report = _script("weather_report")
    folder = ROOT / "benchmark/results/weather"
    result = json.loads((folder / "weather.json").read_text())
    cells = _weather_cells(folder)
    weathers = list(result["datasets"])
    again = weather_report.summarise(cells, weathers, result["bound"])
    assert again["points"].keys() == result["points"].keys()
    for model, rows in result["points"].items():
        for mine, theirs in zip(again["points"][model], rows, strict=True):
            assert mine["weather"] == theirs["weather"] and mine["seeds"] == theirs["seeds"]
            assert mine["accuracy"] == pytest.approx(theirs["accuracy"])
            assert mine["accuracy_ci95"] == pytest.approx(theirs["accuracy_ci95"])
    assert {m: len(c) for m, c in cells.items()} == {
        m + t: 5 for m in ("cnn", "snn_simlidar_tuned", "snntorch_lif") for t in ("", " (mixed)")
    }
    assert list(result["datasets"]) == [
        "clear",
        "200",
        "100",
        "50",
        "30",
        "rain10",
        "rain50",
        "rain100",
        "rain200",
    ]
    for name, dataset in result["datasets"].items():
        run = json.loads((folder / f"bound/runs/{dataset}__near_first-as_value.json").read_text())
        every = [r for r in run["rows"] if r["k"] is None][0]
        assert result["bound"][name]["accuracy"] == pytest.approx(100 * every["accuracy_mean"])
        family = every["learners"][every["best"].split("/")[0]]
        assert result["bound"][name]["family_std"] == pytest.approx(100 * family["accuracy_std"])
    for rows in result["points"].values():
        for row in rows:
            assert row["accuracy"] <= result["bound"][row["weather"]]["accuracy"]


# The committed weather scores above the estimate of their weather (dataset version 5.0.0; two
# MLP families, the CNN family, which the flash and scan estimates have, not run on the weather
# data yet): (row, weather, seed) -> the lead in test samples over the estimate's best seed
# ensemble there. The snnTorch network trained in clear air at 10 mm/h (485 of 600 against 484).
WEATHER_ABOVE_THE_ESTIMATE = {
    ("snntorch_lif", "rain10", 0): 1,
}


def test_every_committed_weather_score_is_at_or_below_the_estimate_but_the_known_ones():
    """Issue 61, item 3: of the 270 committed weather scores (6 rows x 5 seeds x 9 weathers)
    exactly those listed above score above the estimate of the weather they are tested in, each
    by the lead listed, read in test samples as for the flash cells
    (``early_bound.above_the_bound``): up to 5 samples no pattern of right and wrong makes
    significant (McNemar at 5 %), more some patterns would (the cells keep no right or wrong
    per sample to tell); every one leads by less than a lead that every pattern makes
    significant, and its row's mean over seeds is below the estimate.
    weather.json holds the same list, and docs/weather.md's blocks (these scores, the fog and
    rain tables) are what the script writes from it (``weather.py --no-train --doc
    docs/weather.md``), figures and all."""
    weather_estimate, weather_report = _script("weather_estimate"), _script("weather_report")
    reproduction = _script("reproduction_table")
    folder = ROOT / "benchmark/results/weather"
    result = json.loads((folder / "weather.json").read_text())
    cells, names = _weather_cells(folder), result["datasets"]
    runs = weather_estimate.estimate_runs(names, folder / "bound")
    above = weather_estimate.above_the_estimate(cells, names, runs)
    scores = sum(len(c) for c in cells.values()) * len(names)
    assert scores == 270
    found = {(e["variant"], e["weather"], e["seed"]): e["lead"] for e in above}
    assert found == WEATHER_ABOVE_THE_ESTIMATE, found
    for e in above:
        assert e["samples"] == 600 and e["mcnemar_p_max"] > 0.05, e
        assert (e["mcnemar_p_min"] > 0.05) == (e["lead"] <= 5), e
        assert e["seeds_mean"] < e["bound"], e
    assert result["above_the_estimate"] == json.loads(json.dumps(above))
    assert result["bound"] == json.loads(json.dumps(weather_estimate.estimate(runs)))
    page = ROOT / "docs/weather.md"
    _, block, _ = reproduction.split(
        page.read_text(), page, weather_report.DOC_START, weather_report.DOC_END
    )
    assert block == "\n".join(weather_report.above_block(result))
    assert "| snntorch_lif | rain 10 mm/h | 0 | 80.83 (485 of 600) |" in block
    # and the fog and rain tables above it, from the same results
    _, tables, _ = reproduction.split(
        page.read_text(), page, weather_report.TABLES_START, weather_report.TABLES_END
    )
    assert tables == "\n".join(weather_report.tables_block(result))
    assert "| cnn | 80.90 ± 0.72 | 3.17 ± 0.00 |" in tables


def test_weather_reads_a_lead_over_the_estimate_in_test_samples():
    """weather_estimate.above_the_estimate on a made-up run: 600 test samples, the estimate 0.5
    (300, a seed ensemble); a row's seeds at 303 and 290 right: seed 0 leads by 3 (p at least 0.25 =
    2 ** -2), seed 1 is below; its seeds' mean 296.5 is below the estimate. The block names
    the families and says that the CNN family is not in the estimate."""
    weather_estimate, weather_report = _script("weather_estimate"), _script("weather_report")
    family = {"accuracy": [0.49, 0.48], "accuracy_mean": 0.485, "accuracy_std": 0.007,
              "ensemble": 0.5}  # fmt: skip
    run = {
        "seeds": [0, 1],
        "test_samples": 600,
        "learner": {"mlp": {"hidden": [256, 256], "model": "mlp"}},
        "rows": [{"k": None, "accuracy_mean": 0.5, "best": "mlp/ensemble",
                  "learners": {"mlp": family}}],
    }  # fmt: skip
    right = {0: 303, 1: 290}
    cells = {"m": [{"seed": s, "test_accuracy": {"clear": n / 600}} for s, n in right.items()]}
    above = weather_estimate.above_the_estimate(cells, {"clear": "d"}, {"clear": run})
    assert [(e["seed"], e["lead"]) for e in above] == [(0, 3)]
    assert above[0]["mcnemar_p_min"] == 0.25
    assert above[0]["seeds_mean"] == pytest.approx(296.5 / 600)
    estimate = weather_estimate.estimate({"clear": run})
    assert estimate["clear"]["family_mean"] == pytest.approx(48.5)
    summary = {"points": {"m": [{"seeds": [0, 1]}]}, "bound": estimate}
    block = weather_report.above_block(summary | {"above_the_estimate": above})
    assert block[0].startswith(
        "The estimate with every spike: the best of the learner families (mlp: MLP 256-256;"
    )
    assert "The paper's CNN" in block[0] and "1 of the 2 committed scores" in block[0]
    line = "| m | clear air | 0 | 50.50 (303 of 600) | 50.00 (mlp/ensemble) | 50.00 (300) | 3 |"
    assert block[4].startswith(line)
