"""Benchmarks: ``python -m headless bench NAME``. They print figures and ratios; tests never time."""

import argparse

MAX_COUNT = 10_000_000  # the most of anything a benchmark option asks for (targets, points, frames)
MAX_SEED = 2**32 - 1  # numpy's seeds: any 32-bit number (a date, 20240101, is a common one)


def whole(lo: int = 1, hi: int = MAX_COUNT):
    """An argparse type for a count (or a seed, ``lo`` 0): a whole number in [lo, hi], written
    as digits or as a whole number in exponent form ("1e6", as the options' help gives some)."""

    def parse(text: str) -> int:
        try:
            value = float(text) if any(c in text for c in ".eE") else int(text)
        except ValueError:
            value = None
        if value is None or value != value or value in (float("inf"), float("-inf")) or value != int(value) \
                or not lo <= int(value) <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number from {lo} to {hi}, got {text!r}")
        return int(value)

    parse.__name__ = "whole number"  # what argparse names in its message
    return parse


def check_readme_whole(args: argparse.Namespace, **defaults) -> None:
    """``--readme`` rewrites a docs table whole: refused with any of the options named (as
    keyword = default value) given otherwise, since those run part of the table (the rest of
    it was deleted from the page)."""
    if not getattr(args, "readme", False):
        return
    given = [name for name, default in defaults.items() if getattr(args, name) != default]
    if given:
        from addon.core.errors import InputError

        options = " and ".join(f"--{name.replace('_', '-')}" for name in given)
        raise InputError(f"--readme rewrites the docs' whole table and {options} runs part of it: leave "
                         f"{'it' if len(given) == 1 else 'them'} out, or --readme")
