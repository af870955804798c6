"""Headless command line for the laser scanner simulator: ``python -m headless``.

This package file stays import-light: ``headless.bootstrap`` must run on a bare
CPython 3.11 before any dependency is installed.
"""
