"""examples/tutorial.ipynb runs: its code cells in order, in one namespace, as Jupyter would,
and what each step shows is what it says (a dataset of each level, a trained network better
than chance, a lower score on noisier data, objects that move)."""

import json
from pathlib import Path

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "tutorial.ipynb"


def test_the_tutorial_runs_and_shows_what_it_says(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    assert not any(c.get("outputs") for c in cells if c["cell_type"] == "code")  # committed clean
    namespace: dict = {}
    for cell in cells:
        if cell["cell_type"] == "code":
            exec(compile("".join(cell["source"]), str(NOTEBOOK), "exec"), namespace)
    assert namespace["clear"].path.name == "simlidar-4c-noise0.1-paper-v2.0.0"
    assert namespace["x"].shape == (400, 16, 16)
    assert namespace["result"].test_accuracy > 0.5  # four classes: chance is 0.25
    scores = namespace["scores"]
    test_size = 200  # evaluate gives train's figure, to the sample
    assert round(scores[0.1] * test_size) == round(namespace["result"].test_accuracy * test_size)
    assert scores[0.33] < scores[0.1]
    speeds = namespace["samples"].object_motion[:, 0]
    assert speeds[0] == 0.0 and (speeds[1:] > 0).all()  # none stands; car, pedestrian, truck move
