"""The optional compiled span kernel of the emulator (hil/families/fbs/sim/_kernel.c).

Everything else is in pyproject.toml.  ``optional=True``: without a C compiler the install still succeeds and the
emulator runs its Python models alone (the same results, slower; ``hil.families.fbs.sim.kernel.available()`` says which).
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "hil.families.fbs.sim._kernel", ["hil/families/fbs/sim/_kernel.c"], optional=True,
    # bit-for-bit the Python models' arithmetic: no a·b + c fused into one rounding, no fast-math shortcuts
    extra_compile_args=["-ffp-contract=off", "-fno-fast-math", "-std=c11"],
)])
