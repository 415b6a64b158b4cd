"""The compiled parts, all optional (without a C compiler the install goes on):

- `policy._blend_row`, the row blend in C (policy/_blend_row.c); without it `policy.blend_fast`
  uses its Python row blend (the same numbers);
- `policy._belief_row`, a session's belief update and views (policy/_belief_row.c); without it
  `policy.belief` uses numpy (the same numbers);
- `policy._row_forward`, a stack of small MLPs on one observation (policy/_row_forward.c);
  without it (or without AVX2 and FMA) `policy.row_forward` uses numpy.

Everything else is in pyproject.toml.
"""

import numpy
from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "policy._blend_row",
            ["policy/_blend_row.c"],
            include_dirs=[numpy.get_include()],
            depends=["policy/_numpy_order.h"],
            # no fused multiply-add: Python rounds a * b + c twice, and so must this
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        ),
        Extension(
            "policy._belief_row",
            ["policy/_belief_row.c"],
            include_dirs=[numpy.get_include()],
            depends=["policy/_numpy_order.h"],
            extra_compile_args=["-O2", "-ffp-contract=off"],  # numpy's bits: as _blend_row
            optional=True,
        ),
        Extension(
            "policy._row_forward",
            ["policy/_row_forward.c"],
            include_dirs=[numpy.get_include()],
            # the vector code is intrinsics, compiled per CPU variant (target attributes) and
            # chosen at import; no contraction of the plain C either
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        ),
    ]
)
