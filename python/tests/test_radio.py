"""The radio world on NumPy arrays agrees with `dupac radio link` and with itself."""

from __future__ import annotations

import json

import numpy as np

from conftest import run_dupac


def _points(sc, n, seed):
    (x0, y0, x1, y1), (z0, z1) = sc.bounds_m()
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(x0, x1, n), rng.uniform(y0, y1, n), rng.uniform(max(z0, 60.0), z1, n)]
    )


def test_rsrp_of_every_site_agrees_with_the_link_calculator(scenario, small_set, dupac_bin):
    pts = _points(scenario, 6, 0)
    ours = scenario.rsrp_dbm(pts, exact=True)
    los = scenario.los(pts)
    s = scenario.sites()
    lines = []
    for p in pts:
        for j in range(scenario.num_sites):
            lines.append(
                json.dumps(
                    {
                        "bs_xyz": s["position_m"][j].tolist(),
                        "uav_xyz": p.tolist(),
                        "scenario": s["kind"][j],
                        "boresights_deg": s["boresights_deg"][j],
                        "tilt_deg": float(s["electrical_tilt_deg"][j]),
                        "tx_power_dbm": float(s["tx_power_dbm"][j]),
                    }
                )
            )
    out = run_dupac(dupac_bin, small_set, "radio", "link", stdin="\n".join(lines) + "\n")
    theirs = [json.loads(line) for line in out.splitlines()]
    assert len(theirs) == ours.size
    for k, t in enumerate(theirs):
        i, j = divmod(k, scenario.num_sites)
        assert abs(t["rsrp_dbm"] - ours[i, j]) < 1e-9, (i, j, t, ours[i, j])
        assert t["los"] == bool(los[i, j])


def test_best_site_class_and_cache(scenario):
    pts = _points(scenario, 50, 1)
    exact = scenario.rsrp_dbm(pts, exact=True)
    site, best = scenario.best_site(pts, exact=True)
    assert np.array_equal(site, exact.argmax(axis=1)) and np.array_equal(best, exact.max(axis=1))
    cls = scenario.rsrp_class(best)
    assert np.array_equal(cls, np.where(best >= -80, 0, np.where(best >= -100, 1, 2)))
    # The cache interpolates the model on its grid: close to it, not equal.
    cached = scenario.rsrp_dbm(pts)
    assert cached.shape == exact.shape and np.median(np.abs(cached - exact)) < 3.0


def test_coverage_map_is_the_best_server(scenario):
    cov = scenario.coverage(altitude_m=60.0, resolution_m=20.0)
    ny, nx = cov["rsrp_dbm"].shape
    assert cov["serving"].shape == (ny, nx) and cov["los"].shape == (ny, nx)
    iy, ix = np.argwhere(cov["serving"] >= 0)[len(np.argwhere(cov["serving"] >= 0)) // 2]
    r = cov["resolution_m"]
    p = np.array([[cov["x0_m"] + (ix + 0.5) * r, cov["y0_m"] + (iy + 0.5) * r, 60.0]])
    site, best = scenario.best_site(p, exact=True)
    assert site[0] == cov["serving"][iy, ix]
    assert abs(best[0] - cov["rsrp_dbm"][iy, ix]) < 1e-3
