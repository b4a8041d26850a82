"""Time one training step (forward, loss, backward, optimiser) of the spiking networks against
the conventional networks of the same shape, in one process on the same batch:

    python benchmark/ttfs_speed.py [--steps 20] [--threads N] [--device cuda]

* ``scnn_kitti`` against ``cnn`` on a batch of 10 x 1 x 50 x 118 (KITTI front-view crops; the
  paper's batch of 10), target: the SCNN step at most 5 times the CNN step;
* ``snn_simlidar`` against ``mlp`` on a batch of 60 x 1 x 16 x 16 (Sim LiDAR; the recipes'
  batch), target: at most 3 times.

Inputs are the paper profile's kind of delays: uniform in [0, 1) with a quarter of the pixels
at 1.0 (no return), so that both the spiking and the silent paths run. Each figure is the
median over ``--steps`` steps after two warm-up steps, the two networks' steps taken in turn;
the ratio is measured in the same run, so it holds on another machine where the absolute times
do not. ``--device`` runs both networks there (each step ends when the device has finished it);
off the CPU the spiking layers run their torch form, and the script first checks it against the
compiled kernels on the CPU: the spiking network's output spike times on the same batch and
weights (largest difference, and the share of samples whose first output spike is the same
class). docs/performance.md records the figures.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from simlidar.bench.hardware import MAX_THREADS, check_threads, resolve_device
from simlidar.bench.train import batch_loss, make_optimizer
from simlidar.models.registry import build_model, load_recipe
from simlidar.models.training_config import TrainingConfig
from simlidar.script_args import integers, run

MAX_STEPS = 100_000  # timed steps per model

PAIRS = (  # (spiking, conventional, input shape, batch, target ratio)
    ("scnn_kitti", "cnn", (1, 50, 118), 10, 5.0),
    ("snn_simlidar", "mlp", (1, 16, 16), 60, 3.0),
)


def batch(shape, size: int, classes: int, seed: int = 0):
    generator = torch.Generator().manual_seed(seed)
    x = torch.rand(size, *shape, generator=generator)
    x[torch.rand(x.shape, generator=generator) < 0.25] = 1.0
    return x, torch.randint(0, classes, (size,), generator=generator)


def model_of(name: str, x, classes: int, device: str = "cpu") -> torch.nn.Module:
    """Recipe ``name``'s network for inputs like ``x``, weights of seed 0, on ``device``."""
    recipe = load_recipe(name)
    model = build_model(recipe, tuple(x.shape[1:]), classes, torch.Generator().manual_seed(0))
    return model.to(device)


def trainer(name: str, x, y, classes: int, device: str = "cpu"):
    """One training step of recipe ``name`` on (x, y) on ``device``, as a function of no
    arguments that returns once the device has finished the step."""
    training = TrainingConfig.from_table(load_recipe(name)["training"])
    model = model_of(name, x, classes, device)
    optimizer = make_optimizer(model.parameters(), training)
    x, y = x.to(device), y.to(device)
    synchronize = torch.cuda.synchronize if torch.device(device).type == "cuda" else None

    def step():
        _, total = batch_loss(model, x, y, training)
        optimizer.zero_grad()
        total.backward()
        optimizer.step()
        if synchronize is not None:
            synchronize()

    return step


def differences(a: torch.Tensor, b: torch.Tensor, times: bool = False) -> tuple[int, int, float]:
    """Spikes ``a`` and ``b`` (z domain, inf = none) compared: (places where one fires and the
    other does not, places where both fire at different times, the largest such difference;
    with ``times``, of the spike times t = ln z, in the network's time unit)."""
    a, b = a.double().cpu(), b.double().cpu()
    fired_a, fired_b = torch.isfinite(a), torch.isfinite(b)
    both = fired_a & fired_b
    a, b = (a[both].log(), b[both].log()) if times else (a[both], b[both])
    gap = (a - b).abs()
    largest = float(gap.max()) if gap.numel() else 0.0
    return int((fired_a != fired_b).sum()), int((gap > 0).sum()), largest


def agreement(name: str, x, classes: int, device) -> dict:
    """The spiking network on ``device`` (its torch form) against the compiled kernels on the
    CPU, same batch and weights: its input spikes (the encoding, computed on each device), its
    output spikes from those, the share of samples whose first output spike is the same
    class, and the layers run from the CPU's input spikes moved there (whether the layers
    alone are the kernels bit for bit)."""
    cpu, there = model_of(name, x, classes), model_of(name, x, classes, device)
    with torch.no_grad():
        z_cpu, z_there = cpu.input_spikes(x), there.input_spikes(x.to(device))
        out_cpu, out_there = cpu.propagate(z_cpu)[-1], there.propagate(z_there)[-1]
        layers_there = there.propagate(z_cpu.to(device))[-1]
    same = (out_cpu.argmin(dim=1) == out_there.argmin(dim=1).cpu()).double().mean()
    return {
        "input": differences(z_cpu, z_there),
        "inputs": int(torch.isfinite(z_cpu).sum()),
        "output": differences(out_cpu, out_there),
        "same_class": float(same),
        "layers": differences(out_cpu, layers_there),
    }


def best_seconds(rounds: int, *steps) -> list[float]:
    """The least seconds of each function of no arguments over ``rounds`` rounds, the functions
    called in turn in each round (a change of load falls on all of them alike)."""
    times = [[] for _ in steps]
    for _ in range(rounds):
        for step, spent in zip(steps, times):
            start = time.perf_counter()
            step()
            spent.append(time.perf_counter() - start)
    return [min(spent) for spent in times]


def step_seconds(steps: int, *trainers) -> list[float]:
    """Median seconds of a step of each trainer, their steps taken in turn (so that a change of
    load on the machine falls on all of them alike), after two warm-up rounds."""
    times = [[] for _ in trainers]
    for i in range(steps + 2):
        for step, spent in zip(trainers, times):
            start = time.perf_counter()
            step()
            if i >= 2:
                spent.append(time.perf_counter() - start)
    return [statistics.median(t) for t in times]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--steps", type=integers(1, MAX_STEPS, one=True), default=20, help="timed steps per model"
    )
    parser.add_argument(
        "--threads",
        type=integers(1, MAX_THREADS, one=True),
        default=None,
        help="torch threads (default: all)",
    )
    parser.add_argument(
        "--device", default="cpu", help="where both networks run: cpu (default), cuda, cuda:N"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(check_threads(args.threads))
    device = resolve_device(args.device)
    on_cpu = device.type == "cpu"
    where = f"{torch.get_num_threads()} threads" if on_cpu else torch.cuda.get_device_name(device)
    print(f"torch {torch.__version__}, {where}")
    for spiking, conventional, shape, size, target in PAIRS:
        x, y = batch(shape, size, 8 if spiking == "scnn_kitti" else 32)
        classes = 8 if spiking == "scnn_kitti" else 32
        if not on_cpu:
            found = agreement(spiking, x, classes, device)
            (_, moved, most), layers = found["input"], found["layers"]
            print(
                f"{spiking} on {device} (torch form) against the CPU kernels: input spikes "
                f"(the encoding) differ at {moved} of {found['inputs']} (at most {most:.3g}); "
                f"output spikes fire differently at {found['output'][0]} places and differ "
                f"in time at {found['output'][1]} (at most {found['output'][2]:.3g}); the "
                f"first output spike's class the same for {100 * found['same_class']:.1f} % "
                f"of the batch; from the CPU's input spikes the layers' outputs "
                + ("are the kernels' bit for bit" if layers == (0, 0, 0.0) else f"differ: {layers}")
            )
        snn, ann = step_seconds(
            args.steps,
            trainer(spiking, x, y, classes, device),
            trainer(conventional, x, y, classes, device),
        )
        ratio = snn / ann
        print(
            f"{spiking} {1e3 * snn:8.1f} ms, {conventional} {1e3 * ann:6.1f} ms a step "
            f"(batch {size} x {' x '.join(map(str, shape))}): ratio {ratio:.1f} "
            f"(target <= {target:g}: {'met' if ratio <= target else 'not met'})"
        )


if __name__ == "__main__":
    run(main)
