"""The docs' pictures of a sweep in motion (docs/sweeps.md, "Motion").

    python benchmark/motion_pictures.py              # docs/img/sweep-motion.png, sweep-sequence.gif

Simulates ``simlidar sweep --frames 32 --sequence-frames 16 --ego-speed 20 --moving-objects``
(VLP-16 at 600 RPM, the default catalog, seed 0: sequence 0 a tunnel without an object,
sequence 1 a tunnel with an oncoming car) in a temporary folder, draws its ``motion.png`` and
``sequence.gif`` (:func:`simlidar.generator.bev.draw_motion`: the frame with the most car
points raw and deskewed, sequence 1 in the frame of its first pose) and writes them into
``--out`` as ``sweep-motion.png`` and ``sweep-sequence.gif``, both or neither. The same command
gives the same bytes (on the same matplotlib and Pillow). 20 m/s (72 km/h): the ego's 2 m of
travel over a rotation is what sets raw and deskewed apart, at the picture's 11 pixels a metre.
"""

import argparse
import shutil
import tempfile
from pathlib import Path

from simlidar.atomic import write_files
from simlidar.generator.bev import MOTION_PICTURE, SEQUENCE_ANIMATION, draw_motion
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.sweep import SweepConfig, sweep
from simlidar.scene.recipe import load_catalog
from simlidar.script_args import run

ROOT = Path(__file__).resolve().parent.parent
NAMES = {MOTION_PICTURE: "sweep-motion.png", SEQUENCE_ANIMATION: "sweep-sequence.gif"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs/img", help="an existing folder")
    args = parser.parse_args(argv)
    if not args.out.is_dir():
        parser.error(f"--out {str(args.out)!r}: expected an existing folder")
    config = GeneratorConfig(ego_speed_mps=20.0, moving_objects=True)
    with tempfile.TemporaryDirectory() as work:
        chosen = SweepConfig(frames=32, sequence_frames=16)
        made = sweep(config, chosen, load_catalog(), work, progress=False)
        drawn = draw_motion(made / "frames.h5", made)

        def copy(temporaries: list[Path]) -> None:
            for source, temporary in zip(drawn, temporaries):
                shutil.copyfile(source, temporary)

        written = write_files([args.out / NAMES[p.name] for p in drawn], copy, what="pictures")
    for path in written:
        print(f"wrote {path} ({path.stat().st_size:,} bytes)")
    return 0


if __name__ == "__main__":
    run(main)
