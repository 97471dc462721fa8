"""The compiled part of the package: the cyclic pump as a CPython extension (why an extension:
``src/cobot_hmi/native/_cyclic_pump_module.c``; the design: docs/architecture.md). Everything
else about the package is in pyproject.toml; setuptools reads ``ext_modules`` only from here."""

from setuptools import Extension, setup

NATIVE = "src/cobot_hmi/native"

setup(
    ext_modules=[
        Extension(
            "cobot_hmi.native._cyclic_pump",
            sources=[
                f"{NATIVE}/_cyclic_pump_module.c",
                f"{NATIVE}/cyclic_pump.c",
                f"{NATIVE}/cyclic_pump_periodic.c",
            ],
            depends=[f"{NATIVE}/cyclic_pump.h", f"{NATIVE}/cyclic_pump_periodic.h"],
            include_dirs=[NATIVE],
            extra_compile_args=["-std=gnu11", "-O2", "-Wall", "-Wextra"],
            extra_link_args=["-pthread"],
        )
    ]
)
