"""The compiled kernels, all optional (without a C compiler the install goes on and the numpy
reference of each runs instead):

- `policy._blend_row`, the blend of eqs. 8-10 (policy/_blend_row.c; `policy.blend`);
- `policy._belief_row`, a session's belief update and views and the goal likelihoods' table
  (policy/_belief_row.c; `policy.belief_compiled`);
- `policy._row_forward`, a stack of small MLPs on a few rows, AVX2 and FMA (or AVX-512F)
  chosen at run time (policy/_row_forward.c and the layer it includes twice,
  policy/_row_forward_layer.h; `policy.row_forward`);
- `services.rest._number_rows`, a batch body's rows (or states) of numbers read into one
  array (services/rest/_number_rows.c; `services.rest.number_rows`).

Each kernel is checked against its numpy reference within a stated tolerance (tests/policy/),
the rows against pydantic's validation (tests/services/rest/test_number_rows.py).
Everything else is in pyproject.toml.
"""

import sys

import numpy
from setuptools import Extension, setup

# -O3 where GCC's vectoriser finds plain loops to widen (the blend's and the belief's short
# elementwise loops over doubles; the same bits, since without -ffast-math every sum keeps its
# order); the forward is intrinsics throughout and measured the same at either level
OPTIMISE = {"_blend_row": "-O3", "_belief_row": "-O3", "_row_forward": "-O2"}
# the blend finds libmvec with dlopen, in libc itself from glibc 2.34 on, in libdl before
LIBRARIES = {"_blend_row": ["m", "dl"] if sys.platform.startswith("linux") else ["m"]}

setup(
    ext_modules=[
        Extension(
            f"policy.{name}",
            [f"policy/{name}.c"],
            include_dirs=[numpy.get_include()],
            extra_compile_args=[OPTIMISE[name]],
            libraries=LIBRARIES.get(name, ["m"]),
            depends=[f"policy/{name}_layer.h"] if name == "_row_forward" else [],
            optional=True,
        )
        for name in ("_blend_row", "_belief_row", "_row_forward")
    ]
    + [
        Extension(
            "services.rest._number_rows",
            ["services/rest/_number_rows.c"],
            include_dirs=[numpy.get_include()],
            extra_compile_args=["-O2"],
            optional=True,
        )
    ]
)
