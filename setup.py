"""The two kernels kept in C, both optional (without a C compiler the install goes on and the
caller's other path runs instead: numpy's forward, pydantic's validation). Why these two stay in
C, with the figures, is in docs/architecture.md ("Kernels"); every other kernel is numba
(`policy.blend_kernel`, `policy.belief_kernel`), compiled on the installed machine, no
compiler needed.

- `policy._row_forward`, a stack of small MLPs on a few rows, AVX2 and FMA (or AVX-512F)
  chosen at run time (policy/_row_forward.c and the layer it includes twice,
  policy/_row_forward_layer.h; `policy.row_forward`);
- `services.rest._number_rows`, a batch body's rows (or states) of numbers read into one
  array (services/rest/_number_rows.c; `services.rest.number_rows`).

The forward is checked against its numpy reference within a stated tolerance
(tests/policy/test_row_forward.py), the rows against pydantic's validation
(tests/services/rest/test_number_rows.py).
Everything else is in pyproject.toml.
"""

import numpy
from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "policy._row_forward",
            ["policy/_row_forward.c"],
            include_dirs=[numpy.get_include()],
            extra_compile_args=["-O2"],
            libraries=["m"],
            depends=["policy/_row_forward_layer.h"],
            optional=True,
        ),
        Extension(
            "services.rest._number_rows",
            ["services/rest/_number_rows.c"],
            include_dirs=[numpy.get_include()],
            extra_compile_args=["-O2"],
            optional=True,
        ),
    ]
)
