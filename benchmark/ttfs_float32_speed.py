"""What float32 sums would buy the compiled TTFS kernels (issue 43, item 4):

    python benchmark/ttfs_float32_speed.py [--rounds 7] [--threads 1]

``benchmark/ttfs_float32.py`` measured what float32 sums would change (on two committed cells:
no decision, a few spikes in hundreds of thousands); this script measures what they would
save. It makes float32 twins of the two forward kernels of :mod:`simlidar.models.ttfs_kernels`
(``forward``, the dense layer's walk, and ``conv_forward``, the convolution's) from their own
source: every float64 of the walk (running sums, times, the candidate) becomes float32, the
filter's looseness 1e-14 becomes 1e-6 (float32's rounding), nothing else changes. It records
every call the spiking networks of ``benchmark/ttfs_speed.py`` make to the two kernels in one
training step on that script's batches (``snn_simlidar`` on 60 x 1 x 16 x 16,
``scnn_kitti`` on 10 x 1 x 50 x 118, weights of seed 0), then times each call with the
kernel and with its twin, in turn, the best of ``--rounds``, and prints per layer the two
times and their ratio, their sum beside the whole step (``ttfs_speed.trainer``, the median
of as many steps), and the step's ratio if its forward walks took the twins' time (the
backward kernels sum their gradients as they do today). The twins are not used by simlidar:
the cells' bytes are float64's. docs/performance.md records the figures.
"""

import argparse
import inspect
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ttfs_speed import PAIRS, batch, best_seconds, step_seconds, trainer

from simlidar.bench.hardware import MAX_THREADS
from simlidar.script_args import integers, run

MAX_ROUNDS = 1000
KERNELS = ("forward", "conv_forward")
# (float64 form, float32 form) in the two kernels' source, each of which must be found
REWRITES = (
    ("low, high = 1 - 1e-14, 1 + 1e-14", "low, high = np.float32(1 - 1e-6), np.float32(1 + 1e-6)"),
    ("else np.inf", "else np.float32(np.inf)"),
    ("sw - 1.0", "sw - np.float32(1.0)"),
    ("sum_w[m] - 1.0", "sum_w[m] - np.float32(1.0)"),
    ("np.float64", "np.float32"),
    ("(ex > min_excess)", "(ex > np.float32(min_excess))"),
)


def float32_twins() -> dict:
    """``forward`` and ``conv_forward`` compiled with float32 sums, from their source (each
    rewrite of :data:`REWRITES` checked to apply to each kernel)."""
    from simlidar.models import ttfs_kernels

    twins = {}
    for name in KERNELS:
        source = inspect.getsource(getattr(ttfs_kernels, name).py_func)
        for old, new in REWRITES:
            if old not in source:
                raise RuntimeError(f"{name}: {old!r} not in its source (rewrite this script)")
            source = source.replace(old, new)
        space = dict(vars(ttfs_kernels))  # the names the kernel's source uses
        source = source.replace("@njit(cache=True", "@njit(cache=False")
        exec(compile(source, f"<float32 {name}>", "exec"), space)
        twins[name] = space[name]
    return twins


def recorded_calls(name: str, x, y, classes: int) -> list[tuple[str, tuple]]:
    """The forward kernels' calls (kernel, arguments) of one training step of ``name``."""
    from simlidar.models import ttfs_kernels

    calls, real = [], {k: getattr(ttfs_kernels, k) for k in KERNELS}

    def recording(kernel):
        def call(*args):
            calls.append((kernel, args))
            return real[kernel](*args)

        return call

    step = trainer(name, x, y, classes)
    try:
        for kernel in KERNELS:
            setattr(ttfs_kernels, kernel, recording(kernel))
        step()
    finally:
        for kernel in KERNELS:
            setattr(ttfs_kernels, kernel, real[kernel])
    return calls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=integers(1, MAX_ROUNDS, one=True), default=7)
    parser.add_argument(
        "--threads", type=integers(1, MAX_THREADS, one=True), default=1,
        help="torch and numba threads (default 1)",
    )  # fmt: skip
    args = parser.parse_args()
    import numba

    from simlidar.models import ttfs_kernels

    torch.set_num_threads(args.threads)
    numba.set_num_threads(args.threads)
    twins = float32_twins()
    for spiking, _, shape, size, _ in reversed(PAIRS):
        x, y = batch(shape, size, 32)
        calls = recorded_calls(spiking, x, y, 32)
        print(f"{spiking}, batch {tuple(x.shape)}, {args.threads} thread(s):")
        walks64 = walks32 = 0.0
        for layer, (kernel, call_args) in enumerate(calls):
            real = getattr(ttfs_kernels, kernel)
            twin = twins[kernel]
            fired64 = np.isfinite(real(*call_args)[0]).mean()  # also compiles both
            fired32 = np.isfinite(twin(*call_args)[0]).mean()
            t64, t32 = best_seconds(
                args.rounds, lambda f=real, a=call_args: f(*a), lambda f=twin, a=call_args: f(*a)
            )
            print(
                f"  layer {layer} ({kernel}, input {tuple(call_args[0].shape)}): float64 "
                f"{1e3 * t64:.2f} ms, float32 {1e3 * t32:.2f} ms, ratio {t64 / t32:.2f} "
                f"(neurons firing: {fired64:.4f} / {fired32:.4f})"
            )
            walks64, walks32 = walks64 + t64, walks32 + t32
        (step,) = step_seconds(args.rounds, trainer(spiking, x, y, 32))
        print(
            f"  the forward walks: {1e3 * walks64:.1f} ms in float64, {1e3 * walks32:.1f} ms in "
            f"float32 ({walks64 / walks32:.2f}x); the training step {1e3 * step:.1f} ms "
            f"(median of {args.rounds}), of which the walks are {walks64 / step:.0%}; the step "
            f"with float32 walks: {step / (step - walks64 + walks32):.2f}x faster"
        )


if __name__ == "__main__":
    run(main)
