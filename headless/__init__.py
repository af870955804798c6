"""Headless command line for the laser scanner simulator: ``python -m headless``.

This package file stays import-light: ``headless.bootstrap`` must run on a bare
any Python 3 before any dependency is installed (it then finds CPython 3.13).
"""
