"""Would float32 sums keep the decisions of a committed spiking cell? (issue 43, item 4)

    python benchmark/ttfs_float32.py DATA/simlidar-32c-noise0.1-paper-v2.0.0 \\
        [--recipe snn_simlidar_tuned] [--seed 0]

The TTFS layers sum in float64 (the compiled kernels and the torch form alike): each neuron
walks its inputs in time order and fires at the first prefix whose candidate time falls in
its window, a compare on every multiply-add. float32 would double the vector width, if the
decisions held. This script retrains a committed cell of ``benchmark/sweep_decisions.py``
(every column; the network of ``--recipe``, ``--seed``) on the CPU, checks that the retrained
network scores the committed cell's test accuracy to the bit (the kernels are deterministic,
so it is that cell's network), then runs the test split through it twice, with float64 sums
(the kernels) and with float32 sums (the torch form, whose prefix sums run in the same time
order as the kernels' walk, summed in float32), and prints, per layer, the neurons that fire
in one and not the other and the largest difference of the spike times both have; the hidden
spikes in all; and the test samples whose first output spike changes class, and the accuracy
both ways. Also the torch form's forward time on the CPU in each dtype (one thread, the whole
test split, best of three), to set what float32 would buy beside what it would cost.
"""

import argparse
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sweep_decisions import COMMITTED, committed_cell
from ttfs_speed import best_seconds, differences

from simlidar.script_args import integers, run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dataset", type=Path, help="the flash dataset the committed cell names")
    parser.add_argument("--recipe", choices=list(COMMITTED), default="snn_simlidar_tuned")
    parser.add_argument("--seed", type=integers(0, 2**31 - 1, one=True), default=0)
    args = parser.parse_args()
    from simlidar.bench.train import train
    from simlidar.dataset.loaders import load_split
    from simlidar.models import ttfs

    torch.set_num_threads(1)  # the cells' own thread count: the same network
    committed, recipe = committed_cell(args.dataset, args.recipe, args.seed)
    result = train(recipe, args.dataset, seed=args.seed, max_seconds=float("inf"), progress=False)
    same = result.test_accuracy == committed["test_accuracy"]
    print(
        f"{args.recipe} seed {args.seed} on {args.dataset.name}: retrained test accuracy "
        f"{100 * result.test_accuracy:.2f} % (committed cell {100 * committed['test_accuracy']:.2f}"
        f" %: {'the same network' if same else 'NOT the committed network'})"
    )
    net = result.model.eval()
    x, y = load_split(args.dataset, "test")
    x, y = torch.from_numpy(x)[:, None].double(), torch.from_numpy(y)
    with torch.no_grad():
        z = net.input_spikes(x)  # float64 input spikes, as the cells are scored
        wide = net.propagate(z)  # the kernels: float64 sums
        with ttfs.torch_form(sums=torch.float32):
            narrow = net.propagate(z)
        for i, (a, b) in enumerate(zip(wide[1:], narrow[1:]), start=1):
            only, _, gap = differences(a, b, times=True)
            print(
                f"  layer {i}: {only} of {a.numel()} neuron-samples fire one way only; where both "
                f"fire the spike times t = ln z differ by at most {gap:.3g}"
            )
        hidden = [sum(int(torch.isfinite(t).sum()) for t in s[1:-1]) for s in (wide, narrow)]
        first = [s[-1].argmin(dim=1) for s in (wide, narrow)]
        fired = [torch.isfinite(s[-1]).any(dim=1) for s in (wide, narrow)]
        moved = int(((first[0] != first[1]) | (fired[0] != fired[1])).sum())
        right = [100 * float(((f == y) & k).double().mean()) for f, k in zip(first, fired)]
        print(
            f"  hidden spikes: {hidden[0]} (float64) and {hidden[1]} (float32), "
            f"{100 * (hidden[1] - hidden[0]) / max(hidden[0], 1):+.3f} %; test samples whose "
            f"first output spike changes: {moved} of {len(y)}; accuracy {right[0]:.2f} % "
            f"(float64) and {right[1]:.2f} % (float32)"
        )
        seconds = []
        for sums in ttfs.SUM_DTYPES:
            with ttfs.torch_form(sums=sums):
                seconds.append(best_seconds(3, lambda: net.propagate(z))[0])
        print(
            f"  torch form's forward on the test split, one thread: {seconds[0]:.3f} s "
            f"(float64 sums), {seconds[1]:.3f} s (float32): {seconds[0] / seconds[1]:.2f}x"
        )


if __name__ == "__main__":
    run(main)
