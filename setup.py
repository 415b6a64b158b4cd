"""The one compiled part: `policy._blend_row`, the row blend in C (policy/_blend_row.c).

Everything else is in pyproject.toml. The extension is optional: without a C compiler the
install goes on and `policy.blend_fast` uses its Python row blend (the same numbers).
"""

import numpy
from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "policy._blend_row",
            ["policy/_blend_row.c"],
            include_dirs=[numpy.get_include()],
            # no fused multiply-add: Python rounds a * b + c twice, and so must this
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        )
    ]
)
