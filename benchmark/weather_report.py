"""The weather benchmark's report (``benchmark/weather.py``): the seeds' means and intervals,
weather.md, weather.json and weather.png, and the block of scores above the estimate that
docs/weather.md holds between its lines ``DOC_START`` and ``DOC_END``."""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import reproduction_table
from paper_table import interval

# the lines around the blocks of docs/weather.md that --doc writes: the scores above the
# estimate, and the fog and rain tables
DOC_START = "<!-- weather-above-the-estimate:start -->"
DOC_END = "<!-- weather-above-the-estimate:end -->"
TABLES_START = "<!-- weather-tables:start -->"
TABLES_END = "<!-- weather-tables:end -->"


def summarise(found: dict, weathers: list[str], bound: dict) -> dict:
    """Per row of ``found`` and weather of ``weathers``: the seeds' mean, sample std and 95 %
    interval; ``bound`` (the estimate per weather, :func:`estimate`) kept beside them."""
    points = {}
    for model, runs in found.items():
        points[model] = []
        for weather in weathers:
            acc = np.array([100 * r["test_accuracy"][weather] for r in runs])
            points[model].append(
                {
                    "weather": weather,
                    "accuracy": float(acc.mean()),
                    "accuracy_std": float(acc.std(ddof=1)) if len(acc) > 1 else None,
                    "accuracy_ci95": interval(acc),
                    "seeds": [r["seed"] for r in runs],
                }
            )
    return {"points": points, "bound": bound}


def column(weather: str) -> str:
    """A table column's name: clear air, a fog's visibility or a rain's rate."""
    if weather == "clear":
        return "clear air"
    if weather.startswith("rain"):
        return f"rain {weather[4:]} mm/h"
    return f"fog V = {weather} m"


def above_block(summary: dict) -> list[str]:
    """The scores above the estimate (:func:`above_the_estimate`) as weather.md and
    docs/weather.md show them: what the estimate is, a table, how to read it."""
    from early_bound import ABOVE_LEGEND, p_text

    above, bound = summary.get("above_the_estimate", []), summary["bound"]
    scores = sum(len(rows) * len(rows[0]["seeds"]) for rows in summary["points"].values())
    seeds = sorted({b["learner_seeds"] for b in bound.values()})
    families = {n: f for b in bound.values() for n, f in b["families"].items()}
    named = "; ".join(f"{n}: {f}" for n, f in families.items())
    lines = [
        f"The estimate with every spike: the best of the learner families ({named}; "
        f"fresh noise, {'/'.join(map(str, seeds))} learner seeds a family; their seed means and "
        "seed ensembles) trained in that weather."
        + (
            ""
            if "cnn" in families
            else " The paper's CNN, the third family of the flash and scan estimates, is not in "
            "it yet (hours of training here): the estimate can rise when it is."
        )
        + f" {len(above)} of the {scores} committed scores (a cell in a weather) are above it"
        + (":" if above else "."),
    ]
    if not above:
        return lines
    lines += [
        "",
        "| model | weather | seed | accuracy % (right) | estimate % (best) | best ensemble % | "
        "lead (samples) | p at least | p at most | seeds' mean % |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for e in above:
        n = e["samples"]
        lines.append(
            f"| {e['variant']} | {column(e['weather'])} | {e['seed']} | "
            f"{100 * e['accuracy']:.2f} ({round(e['accuracy'] * n)} of {n}) | "
            f"{100 * e['bound']:.2f} ({e['best']}) | {100 * e['ensemble']:.2f} "
            f"({round(e['ensemble'] * n)}) | {e['lead']} | {p_text(e['mcnemar_p_min'])} | "
            f"{p_text(e['mcnemar_p_max'])} | {100 * e['seeds_mean']:.2f} |"
        )
    return [*lines, "", " ".join(ABOVE_LEGEND)]


def tables_block(summary: dict) -> list[str]:
    """docs/weather.md's fog and rain tables: per row, clear air and each fog (then each rain),
    mean ± sample std over its seeds (%), and the estimate with every spike."""
    weathers = [p["weather"] for p in next(iter(summary["points"].values()))]
    seeds = sorted({len(p["seeds"]) for rows in summary["points"].values() for p in rows})
    lines = [
        f"Test accuracy in %, mean ± sample std over {'/'.join(map(str, seeds))} seeds; "
        '"(mixed)": trained on mixed weather.'
    ]
    for title, chosen in (
        ("Fog", [w for w in weathers if w != "clear" and not w.startswith("rain")]),
        ("Rain", [w for w in weathers if w.startswith("rain")]),
    ):
        if not chosen:
            continue
        shown = ["clear", *chosen]
        names = [column(w).replace("fog ", "") for w in shown]
        lines += ["", f"**{title}**", "", f"| model | {' | '.join(names)} |",
                  "| --- |" + " ---: |" * len(shown)]  # fmt: skip
        for model, rows in summary["points"].items():
            by = {r["weather"]: r for r in rows}
            cells = [
                f"{by[w]['accuracy']:.2f}"
                + (f" ± {by[w]['accuracy_std']:.2f}" if by[w]["accuracy_std"] is not None else "")
                for w in shown
            ]
            lines.append(f"| {model} | " + " | ".join(cells) + " |")
        if summary["bound"]:
            estimate = [f"{summary['bound'][w]['accuracy']:.1f}" for w in shown]
            lines.append(
                "| *estimate, every spike (trained in that weather)* | "
                + " | ".join(estimate)
                + " |"
            )
    return lines


def write_doc(path: Path, summary: dict) -> None:
    """Put :func:`tables_block` into ``path`` between its lines TABLES_START and TABLES_END and
    :func:`above_block` between DOC_START and DOC_END."""
    from simlidar.atomic import write_file

    text = path.read_text()
    for start, end, block in (
        (TABLES_START, TABLES_END, tables_block(summary)),
        (DOC_START, DOC_END, above_block(summary)),
    ):
        before, _, after = reproduction_table.split(text, path, start, end)
        text = before + "\n".join(block) + after
    write_file(path, lambda temporary: temporary.write_text(text))
    print(f"{path}: wrote the fog and rain tables and the scores above the estimate")


def write(out: Path, summary: dict, command: str, names: dict) -> None:
    weathers = list(names)
    header = " | ".join(map(column, weathers))
    lines = [
        "# Weather: trained in clear air or on mixed weather, tested in fog and rain",
        "",
        f"Made by `{command}` (`benchmark/weather.py`; its docstring says what is compared). "
        "Test accuracy (%), mean ± sample std over seeds [95 % interval, Student's t]; "
        "(mixed): trained on the mixed train split (row i from weather i mod K); the estimate: "
        "the early-information estimate with every spike on that weather's own data (learners "
        "trained in that weather), the best accuracy of the learners tried, not a bound: a "
        "stronger learner can beat it (docs/paper-table.md); its uncertainty: its best "
        "family's seed mean ± sample std.",
        "",
        "Datasets: " + ", ".join(f"`{n}`" for n in names.values()) + ".",
        "",
        f"| model | {header} |",
        "| --- |" + " ---: |" * len(weathers),
    ]
    for model, rows in summary["points"].items():
        cells = []
        for r in rows:
            text = f"{r['accuracy']:.2f}"
            if r["accuracy_std"] is not None:
                text += f" ± {r['accuracy_std']:.2f}"
            if r["accuracy_ci95"]:
                text += f" [{r['accuracy_ci95'][0]:.2f}, {r['accuracy_ci95'][1]:.2f}]"
            cells.append(f"{text} (n={len(r['seeds'])})")
        lines.append(f"| {model} | " + " | ".join(cells) + " |")
    bound = summary["bound"]
    if bound:
        row = [f"{bound[w]['accuracy']:.1f}" for w in weathers]
        lines.append("| *estimate, every spike* | " + " | ".join(row) + " |")
        spread = [
            f"{bound[w]['family_mean']:.1f} ± {bound[w]['family_std']:.1f} "
            f"({bound[w]['best'].split('/')[0]}, n={bound[w]['learner_seeds']})"
            for w in weathers
        ]
        lines.append("| *its best family's seeds* | " + " | ".join(spread) + " |")
        lines += ["", "## Scores above the estimate", "", *above_block(summary)]
    text = "\n".join(lines) + "\n"
    out.mkdir(parents=True, exist_ok=True)
    (out / "weather.md").write_text(text)
    (out / "weather.json").write_text(
        json.dumps({"command": command, "datasets": names, **summary}, indent=1) + "\n"
    )
    plot(summary, weathers, out / "weather.png")
    print(text)


def plot(summary: dict, weathers: list[str], path: Path) -> None:
    """Accuracy against visibility (clear air at the right) and against rain rate (clear air
    at the left): one colour a model, solid trained in clear air, dashed on mixed weather."""
    from matplotlib.figure import Figure

    fogs = [w for w in weathers if w != "clear" and not w.startswith("rain")]
    rains = [w for w in weathers if w.startswith("rain")]
    panels = [(kind, chosen) for kind, chosen in (("fog", fogs), ("rain", rains)) if chosen]
    fig = Figure(figsize=(6.5 * max(1, len(panels)), 4.5))
    axes = fig.subplots(1, max(1, len(panels)), squeeze=False)[0]
    colours = {}
    for ax, (kind, chosen) in zip(axes, panels):
        values = [float(w[4:] if kind == "rain" else w) for w in chosen]
        clear_at = 2.0 * max(values) if kind == "fog" else 0.5 * min(values)
        shown = ["clear", *chosen]
        x = [clear_at, *values]
        for model, rows in summary["points"].items():
            base = model.split(" (")[0]
            colour = colours.setdefault(base, f"C{len(colours)}")
            picked = [next(r for r in rows if r["weather"] == w) for w in shown]
            mean = [r["accuracy"] for r in picked]
            low = [r["accuracy"] - (r["accuracy_ci95"] or (r["accuracy"],))[0] for r in picked]
            high = [(r["accuracy_ci95"] or (0, r["accuracy"]))[1] - r["accuracy"] for r in picked]
            mixed = "(" in model  # drawn a little to the right, so that the bars show
            at = [v * 1.06 for v in x] if mixed else x
            ax.errorbar(at, mean, yerr=[low, high], fmt="o--" if mixed else "o-", capsize=3,
                        color=colour, label=model)  # fmt: skip
        if summary["bound"]:
            ax.plot(x, [summary["bound"][w]["accuracy"] for w in shown], "k:",
                    label="estimate, every spike (learners trained in that weather)")  # fmt: skip
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks(x, ["clear", *(f"{v:g}" for v in values)])
        unit = "visibility (m)" if kind == "fog" else "rain rate (mm/h)"
        ax.set(xlabel=unit, ylabel="test accuracy (%)", ylim=(0, 101),
               title=f"Tested in {kind} (sensor profile)")  # fmt: skip
        ax.legend(fontsize=7, loc="upper left" if kind == "fog" else "lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
