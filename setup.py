"""Packaging glue that pyproject.toml cannot express (the metadata lives in pyproject.toml).

The repository keeps the standard library and the documentation at the top level (``stdlib/``,
``docs/``); the wheel ships them inside the ``acl`` package (``acl/stdlib/*.acl``,
``acl/docs/*.md``), so nothing named ``stdlib`` lands in site-packages.
:func:`acl._resources.shipped_dir` finds either layout (source checkout or installed wheel).
"""
from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["acl", "acl.*"]), "acl.stdlib", "acl.docs"],
    package_dir={"acl.stdlib": "stdlib", "acl.docs": "docs"},
    package_data={"acl": ["syntax/*.lark", "**/*.json", "py.typed"], "acl.stdlib": ["*.acl"], "acl.docs": ["*.md"]},
    include_package_data=False,
)
