"""Benchmarks: ``python -m headless bench NAME``. They print figures and ratios; tests never time."""
