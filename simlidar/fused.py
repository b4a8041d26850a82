"""The fused multiply-add that the compiled (numba) kernels share, to repeat BLAS's products.

OpenBLAS's double-precision kernels on x86-64 with FMA (the SkylakeX ones this project's
machines run) sum a product's terms into a zeroed accumulator, each term fused into the running
sum: ``fma(a2, b2, fma(a1, b1, fma(a0, b0, 0)))``. A kernel that must give numpy's ``@`` to the
last bit does the same with :func:`fma` (the ray cast's culling,
:mod:`simlidar.sensor.cast_kernels`; the scenes' template copies, :mod:`simlidar.scene.kernels`).
"""

# numba's cache (``cache=True``) recompiles a kernel when the file that defines it changes, not
# when a function it calls from another file does: after changing :func:`fma`, clear the
# cached kernels of its callers (``__pycache__/*.nbi`` and ``*.nbc`` beside their modules).

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, x, y, z):
    """x * y + z rounded once (LLVM's ``llvm.fma``: the CPU's instruction, or libm's exact
    software form where the CPU has none); callable from numba kernels only."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic(
            "llvm.fma", [double], ir.FunctionType(double, [double] * 3)
        )
        return builder.call(fn, args)

    return sig, codegen
