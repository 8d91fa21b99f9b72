"""The planners from Python are the binary's: `dupac plan` on a held-out pair and
`dupac.Planner` + `dupac.fly_path` give the same planned lengths and the same flights."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest

import dupac

from conftest import run_dupac

PAIR = 2
LAMBDA = 1.0


@pytest.fixture(scope="module")
def planner(scenario) -> dupac.Planner:
    return dupac.Planner(scenario)


def _planned_lengths(summary_md: str) -> dict[str, float]:
    """`path` → `planned (m)` from the table `dupac plan` writes."""
    rows = {}
    for line in summary_md.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) > 2 and re.fullmatch(r"-?[0-9.]+", cells[1]):
            rows[cells[0]] = float(cells[1])
    return rows


def test_paths_and_flights_match_dupac_plan(
    scenario, planner, dupac_bin, small_set, world_dir, tmp_path
):
    pairs = scenario.pairs("eval")
    src, dst = pairs["source_m"][PAIR], pairs["destination_m"][PAIR]
    out = tmp_path / "plan"
    run_dupac(
        dupac_bin,
        small_set,
        "plan",
        "--pairs",
        str(world_dir / "eval.jsonl"),
        "--pair",
        str(PAIR),
        "--lambda",
        str(LAMBDA),
        "--out",
        str(out),
    )
    planned = _planned_lengths((out / "summary.md").read_text())
    shortest = planner.shortest(src, dst)
    aware = planner.coverage_aware(src, dst, lam=LAMBDA)
    assert shortest["length_m"] == pytest.approx(pairs["shortest_m"][PAIR], abs=1e-9)
    assert shortest["length_m"] == pytest.approx(planned["shortest"], abs=0.051)
    assert aware["length_m"] == pytest.approx(planned[f"coverage-aware λ={LAMBDA:g}"], abs=0.051)
    # On this pair the coverage-aware path is not the shortest: the comparison tells them apart.
    assert aware["length_m"] > shortest["length_m"] + 1.0
    for path in (shortest, aware):
        w = path["waypoints_m"]
        assert w.shape[1] == 3 and np.array_equal(w[0], src) and np.array_equal(w[-1], dst)
        assert np.sum(np.linalg.norm(np.diff(w, axis=0), axis=1)) == pytest.approx(path["length_m"])

    # The same path flown by the pilot with A3: the binary's per-step CSV, position by position.
    for name, path in (("shortest", shortest), (f"coverage_aware_lambda_{LAMBDA:g}", aware)):
        with (out / f"flight_{name}.csv").open() as f:
            rows = list(csv.DictReader(f))
        summary, steps = dupac.fly_path(scenario, path["waypoints_m"], pair=PAIR)
        assert summary["length"] == len(rows) == len(steps["step"])
        xyz = np.array([[float(r[k]) for k in ("x_m", "y_m", "z_m")] for r in rows])
        np.testing.assert_allclose(steps["position_m"], xyz, atol=0.0006)
        assert [int(r["serving"]) for r in rows] == steps["serving"].tolist()


def test_coverage_aware_needs_the_coverage_and_a_valid_lambda(scenario, planner):
    pairs = scenario.pairs("eval")
    src, dst = pairs["source_m"][0], pairs["destination_m"][0]
    bare = dupac.Planner(scenario, coverage=False)
    assert not bare.has_coverage and planner.has_coverage
    bare.shortest(src, dst)
    with pytest.raises(ValueError, match="coverage"):
        bare.coverage_aware(src, dst, lam=1.0)
    with pytest.raises(ValueError, match="λ|lambda"):
        planner.coverage_aware(src, dst, lam=-1.0)


def test_bad_endpoints_are_refused_with_the_reason(planner):
    with pytest.raises(ValueError, match="altitude band"):
        planner.check_point(np.array([0.0, 0.0, 1e4]))
    with pytest.raises(ValueError, match="outside the flight area"):
        planner.shortest(np.array([1e6, 0.0, 60.0]), np.array([0.0, 0.0, 60.0]))
    with pytest.raises(ValueError, match="finite"):
        planner.check_point(np.array([np.nan, 0.0, 60.0]))
    # Any NumPy layout: a strided view and a row of a Fortran-ordered array.
    strided = np.repeat(np.array([0.0, 0.0, 1e4]), 2)[::2]
    fortran_row = np.asfortranarray(np.array([[0.0, 0.0, 1e4], [1.0, 1.0, 1e4]]))[0]
    for p in (strided, fortran_row):
        assert not p.flags.c_contiguous
        with pytest.raises(ValueError, match="altitude band"):
            planner.check_point(p)
    with pytest.raises(ValueError, match=r"point_m: expected an array of shape \(3,\)"):
        planner.check_point(np.array([0.0, 0.0]))
