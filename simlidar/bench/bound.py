"""The early-information estimate: how early a decision can be right, before any spiking network.

For k input spikes, a conventional classifier is given what has arrived by the k-th spike of
each sample, in the encoding's time order (:func:`simlidar.models.ttfs.encode`): every pixel
whose spike time is at or before the k-th spike's (ties arrive together, as the event-driven
evaluator delivers them) shows its time, every other pixel the k-th spike's time, and a second
channel says arrived (1) or not (0). ``k = None`` is each sample's own spike count: everything
that ever spikes has arrived. Its test accuracy, trained on the same view of the train split
and selected on a validation split, estimates what a network deciding after k spikes can reach
on this data: an estimate from the learners tried, not a bound, since a stronger learner can
beat it (docs/paper-table.md, "How early a decision can be right"). The module, its functions,
:class:`BoundConfig` and the results' keys keep the older name "bound".

The learner: simlidar's MLP (:func:`simlidar.models.conventional.mlp`, two hidden layers of
256 by default) trained with Adam on the view, the epoch with the best validation accuracy
kept (ties: the lower validation loss; the rows of
:func:`simlidar.bench.selection.validation_split`), stopped after ``patience`` epochs without
improvement: the first estimate. The estimate of issue 42 (:data:`LEARNERS`, :func:`bound`'s
``learners``) trains three families (that MLP, a wide one and the paper's CNN on the view as
(2, H, W) images) with the networks' advantages
(fresh noise every epoch, every training row: :attr:`BoundConfig.fresh_noise`) and takes,
per k, the best of their seed means and seed ensembles. Seeded: one torch.Generator per seed
drives the initial weights and the batch order. Times are taken with scale 1 (t in [0, 1]);
the scale does not change the order.

The clock. Under flash timing a spike's time is its pulse's time of flight. Under scan timing
(``simlidar generate --timing scan``) it is the pulse's arrival in the sweep, emission plus
time of flight, and the emission (its column's place in a 9.5 ms window, shifted from sample to
sample by the firing phase by up to a 55 us firing cycle) dwarfs any time of flight (at most
667 ns): fed as they arrive, the range is a ripple the learner does not find (3-6 %, chance 3.1
%, at every k past the first column; benchmark/results/early-bound-scan/). The sensor knows
when it fired each laser, so the estimate on scan-timed data by default reads the sensor's clock
(``clock="sensor"``): spikes still arrive in arrival order, and each pixel shows what is known
of its time of flight at the k-th spike's time T: its time of flight once it has arrived, else
T minus its emission (at least 0), the range it is known to exceed, in units of ``tof_max_ns``.
Under flash timing every emission is 0 and this is the view above. ``clock="arrival"`` feeds
the arrival times as they are.
"""

import base64
import math
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F

from simlidar.bench.selection import SELECTION, better_score, validation_split
from simlidar.models import ttfs
from simlidar.models.conventional import cnn, mlp

KS = (4, 8, 16, 32, 64, 128, 180, 256)  # input spikes arrived; None: each sample's own count


@dataclass(frozen=True)
class BoundConfig:
    hidden: tuple[int, ...] = (256, 256)  # the MLP's hidden layers (the CNN's dense ones)
    lr: float = 1e-3  # Adam's learning rate
    batch_size: int = 128
    max_epochs: int = 100
    patience: int = 10  # epochs without a better validation score before stopping
    validation: float = 0.1  # fraction of each class held out of the train split
    # the networks' advantages (issue 42): the train split's noise drawn anew every epoch from
    # its clean delays, and, once the validation rows (other scenes) chose the epoch count, a
    # second run of that many epochs on every training row, the last epoch kept
    fresh_noise: bool = False
    # the learner: "mlp", or "cnn", the paper's CNN baseline (conv 5x5/2 x48, x24, then the
    # dense layers of ``hidden``) on the view as a (2, H, W) image
    model: str = "mlp"


def learner_model(config: BoundConfig, view: tuple[int, int, int], classes: int, generator):
    """The learner of ``config`` for views of shape ``view`` (2, H, W)."""
    if config.model == "cnn":
        return cnn(view, classes, generator, dense=config.hidden)
    return mlp(view, classes, generator, dense=config.hidden)


def spike_times(
    delays: np.ndarray,
    no_return: float,
    direction: str = ttfs.NEAR_FIRST,
    missing: str = ttfs.AS_VALUE,
) -> np.ndarray:
    """(N, P) spike times t in [0, 1] of (N, ...) delays by the encoding (inf: no spike). A
    missing return's channel of its own (``own_channel``) is refused: the view has an arrived
    channel already (:func:`arrived`)."""
    if missing == ttfs.OWN_CHANNEL:
        raise ValueError(f"missing={missing!r}: expected one pixel a spike time (the view's own "
                         "arrived channel tells a missing return)")  # fmt: skip
    d = torch.from_numpy(np.asarray(delays, dtype=np.float64).reshape(len(delays), -1))
    return torch.log(ttfs.encode(d, 1.0, no_return, direction, missing)).numpy()


def arrived(
    times: np.ndarray,
    k: int | None,
    emission: np.ndarray | None = None,
    scale: float = 1.0,
    until: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """What has arrived by the k-th spike of each sample (or by the time ``until``).

    times : (N, P) spike times, inf = no spike; k : spikes, None for each sample's own count
    emission : (N, P) when each pixel's pulse left, in the units of ``times`` (the sensor's
        clock), or None; a pixel then shows its time minus its emission (at least 0), times
        ``scale``
    until : (N,) each sample's time, in the units of ``times``, or None: the view at that
        time instead of the k-th spike's (``k`` is then not read)
    returns : (N, 2, P) float32 view (times, arrived mask), (N,) spikes arrived
    """
    spiking = np.isfinite(times)
    ordered = np.sort(times, axis=1)  # inf last
    counts = spiking.sum(axis=1)
    if until is not None:
        nth = np.asarray(until, dtype=np.float64)
    elif k is None:
        nth = np.where(counts > 0, ordered[np.arange(len(times)), np.maximum(counts - 1, 0)], 0.0)
    else:
        index = np.clip(np.minimum(k, counts) - 1, 0, None)  # fewer spikes: all arrived
        nth = np.where(counts > 0, ordered[np.arange(len(times)), index], 0.0)
    mask = spiking & (times <= nth[:, None])
    shown = np.where(mask, times, nth[:, None])
    if emission is not None:
        shown = np.maximum(shown - emission, 0.0) * scale
    view = np.stack([shown, mask], axis=1).astype(np.float32)
    return view, mask.sum(axis=1)


def train_learner(
    x: np.ndarray,
    y: np.ndarray,
    classes: int,
    seed: int,
    config: BoundConfig = BoundConfig(),
    draw=None,
    height: int = 1,
    standardise: str = "pixel",
):
    """Train the learner on (x, y) (N, 2, P), selecting on a validation split.

    classes : the class count C (the learner's outputs)
    seed : the seed of its initial weights, batch order and validation rows
    config : the learner (:class:`BoundConfig`: its family, layers and training)
    draw : a function giving the training view (N, 2, P) anew, one call an epoch (fresh noise;
        ``x`` is then the file's draw, which the validation rows keep): the epoch count chosen
        on the validation rows, the learner is trained again on every row for that many
        epochs and its last epoch kept (:attr:`BoundConfig.fresh_noise`)
    returns : (scores, record): ``scores(view)`` the trained learner's class probabilities
        (M, classes) of any (M, 2, P) view; record {"val_accuracy", "best_epoch", "epochs"},
        and with ``draw`` "refit_epochs"
    height : the samples' rows H (P = H x W): the CNN sees the view as (2, H, W) images; the
        MLP reads (2, 1, P), the same numbers in the same order
    standardise : "pixel" (the estimate's): each feature (pixel and channel) by its own mean and
        standard deviation over the training rows; "channel": each channel by one mean and
        deviation over every pixel (benchmark/ablation/cnn_learner_inputs.py)
    """
    # each feature standardised by the training rows (a time that differs by 0.01 between
    # classes must not look like a constant), then (N, 2, 1, P): the MLP's (C, H, W), or the
    # samples' own (N, 2, H, W) for the CNN
    if standardise == "pixel":
        mean, std = x.mean(axis=0), np.maximum(x.std(axis=0), 1e-3)
    elif standardise == "channel":
        mean = np.broadcast_to(x.mean(axis=(0, 2))[:, None], x.shape[1:])
        std = np.broadcast_to(np.maximum(x.std(axis=(0, 2)), 1e-3)[:, None], x.shape[1:])
    else:
        raise ValueError(f"standardise={standardise!r}: expected 'pixel' or 'channel'")
    view = (x.shape[1], height, x.shape[-1] // height) if config.model == "cnn" else None

    def shaped(a: np.ndarray) -> torch.Tensor:
        a = ((a - mean) / std).astype(np.float32)
        return torch.from_numpy(a.reshape(len(a), *view) if view else a[:, :, None])

    names = [str(c) for c in range(classes)]
    rows, held = validation_split(y, config.validation, seed, names)
    views = (lambda: shaped(draw())) if draw is not None else (lambda: shaped(x))
    xv, yv = shaped(x[held]), torch.from_numpy(y[held]).long()
    generator = torch.Generator().manual_seed(seed)
    model = learner_model(config, view or (2, 1, x.shape[-1]), classes, generator)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    best, best_epoch, best_state, epoch = None, 0, None, 0
    for epoch in range(config.max_epochs):
        _epoch(model, optimizer, views()[rows], torch.from_numpy(y[rows]).long(), generator, config)
        model.eval()
        with torch.no_grad():
            out = model(xv)
        score = ((out.argmax(1) == yv).float().mean().item(), F.cross_entropy(out, yv).item())
        if better_score(score, best):
            best, best_epoch = score, epoch
            best_state = {n: t.clone() for n, t in model.state_dict().items()}
        elif epoch - best_epoch >= config.patience:
            break
    record = {"val_accuracy": best[0], "best_epoch": best_epoch, "epochs": epoch + 1}
    if draw is None:
        model.load_state_dict(best_state)
    else:  # every row, as many epochs as validation chose, the last kept
        generator = torch.Generator().manual_seed(seed)
        model = learner_model(config, view or (2, 1, x.shape[-1]), classes, generator)
        optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
        for _ in range(best_epoch + 1):
            _epoch(model, optimizer, views(), torch.from_numpy(y).long(), generator, config)
        record["refit_epochs"] = best_epoch + 1
    model.eval()

    def scores(view: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return torch.softmax(model(shaped(view)), 1).numpy()

    return scores, record


def fit(
    x: np.ndarray,
    y: np.ndarray,
    x_test: np.ndarray,
    y_test: np.ndarray,
    classes: int,
    seed: int,
    config: BoundConfig = BoundConfig(),
    draw=None,
    keep_scores: bool = False,
    height: int = 1,
) -> dict:
    """Train the learner on (x, y) (N, 2, P) (:func:`train_learner`) and score the test view.

    x_test, y_test : the test split's view (M, 2, P) (:func:`arrived`) and labels (M,)
    classes, seed, config, draw : :func:`train_learner`'s: the class count, the seed, the
        learner (:class:`BoundConfig`) and None or the function that draws the training view
        anew every epoch
    keep_scores : also return the test rows' class probabilities
    height : the samples' rows H (P = H x W), which the CNN reads (:func:`train_learner`)
    returns : {"accuracy", "val_accuracy", "best_epoch", "epochs"} (and "refit_epochs" with
        ``draw``); with ``keep_scores`` also "scores", the test rows' class probabilities
    """
    scores, record = train_learner(x, y, classes, seed, config, draw, height)
    probabilities = scores(x_test)
    result = {"accuracy": float((probabilities.argmax(1) == y_test).mean()), **record}
    return {**result, "scores": probabilities} if keep_scores else result


def _epoch(model, optimizer, x: torch.Tensor, y: torch.Tensor, generator, config) -> None:
    """One epoch of the learner over (x, y) in a seeded order."""
    model.train()
    order = torch.randperm(len(y), generator=generator)
    for i in range(0, len(order), config.batch_size):
        batch = order[i : i + config.batch_size]
        loss = F.cross_entropy(model(x[batch]), y[batch])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()


# the learner families whose best an estimate's row gives (issue 42): the published MLP, a wider
# one and the paper's CNN, all with the networks' advantages; each also as the ensemble of its
# seeds' learners
LEARNERS = {
    "mlp": BoundConfig(fresh_noise=True),
    "wide": BoundConfig(hidden=(1024, 1024), fresh_noise=True),
    "cnn": BoundConfig(hidden=(256,), fresh_noise=True, model="cnn"),
}


def bound(
    train: tuple[np.ndarray, np.ndarray],
    test: tuple[np.ndarray, np.ndarray],
    classes: int,
    no_return: float = 1.0,
    direction: str = ttfs.NEAR_FIRST,
    missing: str = ttfs.AS_VALUE,
    ks=KS,
    seeds=(0, 1, 2),
    config: BoundConfig = BoundConfig(),
    emission: tuple[np.ndarray, np.ndarray] | None = None,
    scale: float = 1.0,
    fresh=None,
    learners: dict[str, BoundConfig] | None = None,
    columns=(),
) -> dict:
    """The estimate on (delays (N, ...), labels (N,)) train and test splits: one row per k (and
    one for each sample's own count, ``k`` None), each with the test accuracy of every seed
    and the spikes that had arrived in the test split (ours: every spike at or before the
    k-th's time; the authors' rule: those after t = 0). ``emission``: the train and test
    splits' (N, ...) emission times in delay units, read by the sensor's clock
    (:func:`arrived`, near first only: far first reverses time, and a clock with it).
    ``fresh``: with :attr:`BoundConfig.fresh_noise`, ``fresh(seed)`` gives a function that
    draws the train split's delays anew (:func:`simlidar.bench.augment.fresh_noise`).

    classes : the class count C (the learners' outputs)
    no_return, direction, missing : the encoding (:func:`simlidar.models.ttfs.encode`): delays
        at or above ``no_return`` are no return (inf: every pixel spikes), which delay spikes
        first, and what a missing return becomes
    ks : the counts k of input spikes arrived, one row each in this order (:data:`KS`); the
        row of each sample's own count comes last
    seeds : one learner trained per seed (its initial weights, batch order and validation rows)
    config : the one learner without ``learners`` (:class:`BoundConfig`)
    scale : with ``emission``, delay units to units of ``tof_max``: the view's times are
        multiplied by it (:func:`arrived`; 1.0: left as they are)
    learners : name -> configuration of several learner families (:data:`LEARNERS`); each row
        then holds every family's per-seed accuracies and the accuracy of its seeds' ensemble
        (their class probabilities averaged), and ``accuracy_mean`` is the best of those
        (``best`` names it): the estimate, which a stronger learner can beat. Without it, one
        learner (``config``), as the published runs before issue 42.
    columns : scan-timed data on the sensor's clock (``emission``): also one row per count C
        of the sweep's first firings (``column_rows``), each sample seen when the last pulse
        of its first C columns has had its listening window (that pulse's emission plus
        ``tof_max``, 1 / ``scale`` in delay units): the view of every sensor time from then
        until the next firing, when a network fed those columns decides
        (benchmark/sweep_decisions.py); ``until_median`` is that time's median, delay units.
    """
    if emission is not None and direction != ttfs.NEAR_FIRST:
        raise ValueError(f"direction={direction!r}: the sensor's clock reads near_first times")
    times, fired = _split_times(train, test, no_return, direction, missing, emission)
    if columns and emission is None:
        raise ValueError("columns: expected scan-timed data on the sensor's clock (emission)")
    families = learners or {"mlp": config}
    height = train[0].shape[1] if train[0].ndim == 3 else 1  # (N, H, W) delays: H rows
    points = [("k", k, (None, None)) for k in [*ks, None]]
    for c in columns:  # when the last pulse of the first c columns is back, per sample
        ends = [e.reshape(len(e), -1, e.shape[-1])[..., :c].max(axis=(1, 2)) for e in emission]
        points.append(("columns", c, tuple(end + 1.0 / scale for end in ends)))
    rows, column_rows = [], []
    for key, k, until in points:
        kk = k if key == "k" else None
        (x, _), (x_test, got) = (
            arrived(t, kk, e, scale, u) for t, e, u in zip(times, fired, until)
        )
        after_zero = ((x_test[:, 1] > 0) & (times[1] > 0)).sum(axis=1)
        found = {}
        for name, learner in families.items():
            runs = []
            for seed in seeds:
                draw = None
                if learner.fresh_noise:
                    delays = fresh(seed)
                    view = (kk, no_return, direction, missing, fired[0], scale, until[0])
                    draw = _view_draw(delays, *view)
                fitted = fit(
                    x, train[1], x_test, test[1], classes, seed, learner, draw, True, height
                )
                runs.append(fitted)
            found[name] = _family(runs, test[1])
        row = {
            key: k,
            "input_spikes_median": float(np.median(got)),
            "input_spikes_mean": float(got.mean()),
            "input_spikes_authors_mean": float(after_zero.mean()),
        }
        if key == "columns":
            row["until_median"] = float(np.median(until[1]))
        if learners is None:
            (only,) = found.values()
            accuracy = only["accuracy"]
            row.update(
                accuracy=accuracy,
                accuracy_mean=float(np.mean(accuracy)),
                accuracy_std=float(np.std(accuracy)),
                runs=only["runs"],
            )
        else:
            row.update(best_of(found))
        (rows if key == "k" else column_rows).append(row)
    learner = {**asdict(config), "model": "mlp", "selection": SELECTION}
    if learners is not None:
        learner = {name: asdict(c) for name, c in learners.items()}
    result = {
        "encoding": {"direction": direction, "missing": missing, "no_return": no_return},
        "seeds": list(seeds),
        "learner": learner,
        "spikes_total_mean": float(np.isfinite(times[1]).sum(axis=1).mean()),
        "test_samples": len(test[1]),
        "rows": rows,
    }
    return {**result, "column_rows": column_rows} if columns else result


def best_of(found: dict[str, dict]) -> dict:
    """A row's estimate from its learner families ``found`` (name -> :func:`_family`): the best of
    every family's seed mean and seed ensemble, named (``mlp``, ``wide/ensemble``, ...)."""
    best = max(
        ((f"{n}{form}", f[key]) for n, f in found.items()
         for form, key in (("", "accuracy_mean"), ("/ensemble", "ensemble"))),
        key=lambda pair: pair[1],
    )  # fmt: skip
    family = found[best[0].split("/")[0]]
    return {
        "accuracy": family["accuracy"],
        "accuracy_mean": best[1],
        "accuracy_std": family["accuracy_std"],
        "best": best[0],
        "learners": found,
    }


def with_families(result: dict, extra: dict) -> dict:
    """An estimate of several learner families (``result``) with the families of ``extra``
    added: a run of other families on the same data, encoding, seeds, k and columns; every row's
    estimate taken again over all of them."""
    if extra["seeds"] != result["seeds"] or extra["encoding"] != result["encoding"]:
        raise ValueError("with_families: expected runs of the same seeds and encoding")
    merged = {**result, "learner": {**result["learner"], **extra["learner"]}}
    merged["test_samples"] = result.get("test_samples", extra["test_samples"])
    for name in ("rows", "column_rows"):
        pairs = list(zip(result.get(name, []), extra.get(name, []), strict=True))
        if any(a.get("k") != b.get("k") or a.get("columns") != b.get("columns") for a, b in pairs):
            raise ValueError(f"with_families: the runs' {name} differ")
        if pairs:
            merged[name] = [{**a, **best_of({**a["learners"], **b["learners"]})} for a, b in pairs]
    return merged


def _split_times(train, test, no_return, direction, missing, emission):
    """The train and test splits' spike times (N, P) by the encoding, and their emission times
    (N, P) (None each under flash timing)."""
    times = [spike_times(s[0], no_return, direction, missing) for s in (train, test)]
    fired = [None, None] if emission is None else [e.reshape(len(e), -1) for e in emission]
    return times, fired


def _family(runs: list[dict], y_test: np.ndarray) -> dict:
    """One learner family's seeds at one k: accuracies (sample standard deviation) and the
    accuracy of their ensemble; the runs' records without their scores."""
    accuracy = [r["accuracy"] for r in runs]
    ensemble = np.mean([r["scores"] for r in runs], axis=0).argmax(1)
    return {
        "accuracy": accuracy,
        "accuracy_mean": float(np.mean(accuracy)),
        "accuracy_std": float(np.std(accuracy, ddof=1)) if len(accuracy) > 1 else 0.0,
        "ensemble": float((ensemble == y_test).mean()),
        "ensemble_correct": pack(ensemble == y_test),  # per test sample (rounded_up_accuracy)
        "runs": [{k: v for k, v in r.items() if k != "scores"} for r in runs],
    }


def per_sample(
    train: tuple[np.ndarray, np.ndarray],
    test: tuple[np.ndarray, np.ndarray],
    classes: int,
    no_return: float = 1.0,
    direction: str = ttfs.NEAR_FIRST,
    missing: str = ttfs.AS_VALUE,
    seeds=(0, 1, 2),
    config: BoundConfig = LEARNERS["wide"],
    emission: tuple[np.ndarray, np.ndarray] | None = None,
    scale: float = 1.0,
    fresh=None,
) -> dict:
    """The estimate's per-sample form: one learner per seed trained on views at any k (each
    training row at its own k, drawn uniformly from 1..P anew every epoch), then asked about
    every test sample at every k. A network that decided sample i after k_i input spikes is
    compared with the mean over i of whether the learner is right on sample i's view at k_i
    (:func:`per_sample_accuracy`): the learner shown each test sample's view at that sample's
    own decision count. One learner for every k is weaker than the per-k ones near the full
    count (97.5 % against 99.8 % at k = 256, near first, noise 0.1), and networks beat it there;
    :func:`rounded_up_accuracy` is the per-sample form that holds. The arguments are
    :func:`bound`'s.

    train, test, classes, no_return, direction, missing, seeds : :func:`bound`'s
    config : the one learner of every seed (:class:`BoundConfig`; by default the wide MLP of
        :data:`LEARNERS`, with fresh noise, which then needs ``fresh``)
    emission, scale, fresh : :func:`bound`'s
    returns : {"learner", "seeds", "k_max": P, "samples": N, "correct": {seed or "ensemble":
        the (P, N) matrix of right answers at k = 1..P, packed (:func:`unpack`)}}
    """
    times, fired = _split_times(train, test, no_return, direction, missing, emission)
    points, n = times[1].shape[1], len(train[1])
    views = [arrived(times[1], k, fired[1], scale)[0] for k in range(1, points + 1)]
    correct, summed = {}, 0.0
    for seed in seeds:
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(13,))))
        x, _ = arrived(times[0], rng.integers(1, points + 1, size=n), fired[0], scale)
        draw = None
        if config.fresh_noise:
            delays = fresh(seed)

            def draw(delays=delays, rng=rng) -> np.ndarray:
                t = spike_times(delays(), no_return, direction, missing)
                return arrived(t, rng.integers(1, points + 1, size=n), fired[0], scale)[0]

        scores, _ = train_learner(x, train[1], classes, seed, config, draw)
        probabilities = np.stack([scores(view) for view in views])  # (P, N, classes)
        correct[str(seed)] = pack(probabilities.argmax(2) == test[1])
        summed = summed + probabilities
    correct["ensemble"] = pack(summed.argmax(2) == test[1])
    return {
        "learner": asdict(config),
        "seeds": list(seeds),
        "k_max": points,
        "samples": len(test[1]),
        "correct": correct,
    }


def pack(matrix: np.ndarray) -> str:
    """A boolean matrix as base64 of its packed bits (its shape is the caller's to keep)."""
    return base64.b64encode(np.packbits(matrix.astype(bool), axis=None).tobytes()).decode()


def unpack(text: str, shape: tuple[int, int]) -> np.ndarray:
    """:func:`pack`'s matrix of ``shape``."""
    bits = np.unpackbits(np.frombuffer(base64.b64decode(text), dtype=np.uint8))
    return bits[: shape[0] * shape[1]].reshape(shape).astype(bool)


def per_sample_accuracy(form: dict, spikes, which: str = "ensemble") -> float:
    """The per-sample estimate (:func:`per_sample`) for a network that decided each test sample
    after ``spikes`` (N,) input spikes (0 counts as 1: a decision before any spike reads
    nothing, the view of the first spike knows at least as much): the share of test samples
    the learner (``which``: a seed, or the ensemble of the seeds) gets right at that count."""
    correct = unpack(form["correct"][which], (form["k_max"], form["samples"]))
    k = np.clip(np.asarray(spikes, dtype=np.int64), 1, form["k_max"])
    return float(correct[k - 1, np.arange(form["samples"])].mean())


def test_samples(result: dict) -> int:
    """The test samples of :func:`bound`'s result; in runs that predate the field, read from
    the packed per-sample answers (exact where the count is a multiple of 8, as 600 is)."""
    if "test_samples" in result:
        return result["test_samples"]
    family = next(iter(result["rows"][0]["learners"].values()))
    return 8 * len(base64.b64decode(family["ensemble_correct"]))


def rounded_up_accuracy(result: dict, spikes) -> float:
    """A looser per-sample estimate from :func:`bound`'s rows (several learners): each test
    sample counted right where the best family's ensemble at the first measured k at or above
    its decision count ``spikes`` (N,) (the row of every spike beyond the largest) is right.
    That learner saw at least as much of the sample as the network had."""
    rows = sorted(result["rows"], key=lambda r: math.inf if r["k"] is None else r["k"])
    ks = np.array([math.inf if r["k"] is None else r["k"] for r in rows])
    spikes = np.asarray(spikes)
    right = []
    for row in rows:  # (rows, N): the best family's ensemble right or wrong on each sample
        family = max(row["learners"].values(), key=lambda f: f["ensemble"])
        right.append(unpack(family["ensemble_correct"], (1, len(spikes)))[0])
    first = np.searchsorted(ks, spikes, side="left")  # the first measured k >= the count
    return float(np.array(right)[first, np.arange(len(spikes))].mean())


def _view_draw(delays, k, no_return, direction, missing, emission, scale, until=None):
    """A function giving the training view at ``k`` (or ``until``) of a fresh draw of
    ``delays()``."""

    def draw() -> np.ndarray:
        times = spike_times(delays(), no_return, direction, missing)
        return arrived(times, k, emission, scale, until)[0]

    return draw


CLOCKS = ("sensor", "arrival")


def sensor_clock(dataset, split: str) -> tuple[np.ndarray, float] | None:
    """A scan-timed split's emission times in delay units (N, H, W) and the scale from delay
    units to ``tof_max_ns``; None for flash timing (every emission is 0)."""
    from simlidar.dataset.loaders import load_split, split_info

    attrs = split_info(dataset, split).attrs
    if attrs.get("timing") != "scan":
        return None
    unit = float(attrs["delay_unit_ns"])
    return load_split(dataset, split, "emission_ns")[0] / unit, unit / float(attrs["tof_max_ns"])


def dataset_bound(
    dataset, direction=ttfs.NEAR_FIRST, missing=ttfs.AS_VALUE, clock="sensor", **options
) -> dict:
    """:func:`bound` on a dataset directory's train and test splits, with its profile's
    no-return rule (:func:`simlidar.dataset.loaders.spike_threshold`); a scan-timed dataset's
    by ``clock`` (:data:`CLOCKS`; the result's ``encoding`` then names it)."""
    from simlidar.dataset.loaders import load_split, spike_threshold, split_info

    if clock not in CLOCKS:
        raise ValueError(f"clock={clock!r}: expected one of {CLOCKS}")
    attrs = split_info(dataset, "train").attrs
    train, test = load_split(dataset, "train"), load_split(dataset, "test")
    classes = len(attrs["class_names"])
    scan = attrs.get("timing") == "scan"
    if scan and clock == "sensor":
        (e_train, scale), (e_test, _) = (sensor_clock(dataset, s) for s in ("train", "test"))
        options.update(emission=(e_train, e_test), scale=scale)
    configs = [options.get("config", BoundConfig()), *options.get("learners", {}).values()]
    if any(c.fresh_noise for c in [*configs, options.get("per_sample") or BoundConfig()]):
        from simlidar.bench.augment import fresh_noise

        rows = np.arange(len(train[1]))
        options["fresh"] = lambda seed: fresh_noise(dataset, attrs, seed, rows)
    form = options.pop("per_sample", None)  # a BoundConfig: also the per-sample form
    result = bound(train, test, classes, spike_threshold(attrs), direction, missing, **options)
    if form is not None:
        keep = {k: options[k] for k in ("seeds", "emission", "scale", "fresh") if k in options}
        result["per_sample"] = per_sample(
            train, test, classes, spike_threshold(attrs), direction, missing, config=form, **keep
        )
    if scan:
        result["encoding"]["clock"] = clock
        unit_us = float(attrs["delay_unit_ns"]) / 1000.0
        for row in result.get("column_rows", []):
            row["time_us_median"] = row.pop("until_median") * unit_us
    return result
