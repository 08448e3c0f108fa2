"""Bad scenario files through the command lines, refused at once (benchmarks/fuzz_scenarios.py).

Every case of the seeded fuzz (NaN, infinity, negative, zero, huge, wrong type and
missing values of the bundled scenarios' keys; empty, corrupt and open mesh files; an
empty program, one without a spindle speed, a line range that selects nothing; sizes
beyond the memory budget; counts beyond their limits) must end in one line naming the
scenario file and the key, with exit status 2, and within FAST_S: before any long work
(the reported cases took 17-245 s to fail, or ran on with an empty report).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: A refusal must come within this [s] (loading a scenario: reading its meshes and
#: program, a few tenths of a second; the cases' time limit is twice it).
FAST_S = 5.0


def _fuzz():
    spec = importlib.util.spec_from_file_location(
        "fuzz_scenarios", ROOT / "benchmarks" / "fuzz_scenarios.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


FUZZ = _fuzz()
CASES = FUZZ.cases(seed=19)


@pytest.fixture(scope="module", autouse=True)
def _imports():
    """The command lines' own imports, once, outside the cases' time."""
    import errpred.pipeline  # noqa: F401
    import orient.plan  # noqa: F401
    import sim.job_cli  # noqa: F401


def test_fuzz_makes_enough_cases():
    all_cases = FUZZ.cases(seed=19)
    assert len(all_cases) >= 78
    assert len({c.name for c in all_cases}) == len(all_cases)
    assert {c.package for c in all_cases} == {"errpred", "orient"}


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_scenario_is_one_line_exit_2_at_once(case, tmp_path):
    out = FUZZ.run_case(case, tmp_path, seed=19, limit_s=2 * FAST_S)
    assert out.verdict == "input error", (out.verdict, out.stderr[-2000:])
    assert out.seconds < FAST_S, out.seconds


def test_toml_writer_round_trips():
    import tomllib

    doc = tomllib.loads(FUZZ.ORIENT.read_text())
    assert tomllib.loads(FUZZ.dumps(doc)) == doc
