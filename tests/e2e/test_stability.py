"""The stability catalogue (python -m headless bench stability) in CI: every case must
end in a bounded error or a clean, counted rejection. Each case states its own bound
(see headless/bench/stability.py); the README's table is the same run's output."""

import pytest

from headless.bench.stability import CASES, run_case


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_case(case):
    out = run_case(case)
    assert out.ok, f"{case.name}: expected {case.expected}; measured {out.measured}"
