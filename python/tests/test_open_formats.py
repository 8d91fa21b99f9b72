"""What the binary writes, read by other programs' own readers: the run's metrics by
TensorBoard, the evaluation records by pandas."""

from __future__ import annotations

import json

from conftest import prerequisite, run_dupac


def test_tensorboard_reads_the_runs_scalars(trained):
    try:
        from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    except ImportError:
        prerequisite(False, "the tensorboard package (pip install './python[test]')")
    run = trained["learned"].parent
    acc = EventAccumulator(str(run))
    acc.Reload()
    tags = acc.Tags()["scalars"]
    for tag in ("charts/episodic_return", "charts/SPS", "losses/value_loss", "losses/entropy"):
        assert tag in tags, (tag, tags)
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    ret = acc.Scalars("charts/episodic_return")
    assert [e.step for e in ret] == [int(r["global_step"]) for r in rows]
    for e, r in zip(ret, rows):
        assert abs(e.value - r["charts/episodic_return"]) <= 1e-5 * max(1.0, abs(r["charts/episodic_return"]))


def test_pandas_reads_the_evaluation_records(trained, small_set, dupac_bin, tmp_path):
    try:
        import pandas as pd
    except ImportError:
        prerequisite(False, "the pandas package (pip install './python[test]')")
    out = tmp_path / "eval"
    run_dupac(
        dupac_bin, small_set, "eval", "--no-planners", "--no-replay",
        "--policy", f"dupac={trained['learned']}", "--policy", f"base={trained['a3']}",
        "--out", str(out),
    )
    summary = pd.read_csv(out / "summary.csv").set_index("method")
    for method in ("dupac", "base"):
        flights = pd.read_csv(out / "records" / f"{method}__seed0.flights.csv.gz")
        steps = pd.read_csv(out / "records" / f"{method}__seed0.steps.csv.gz")
        row = summary.loc[method]
        assert len(flights) == row["flights"]
        assert abs((flights.outcome == "goal").mean() - row["success"]) < 1e-12
        assert abs((flights.outcome == "time_limit").mean() - row["timeout"]) < 1e-12
        per_flight = steps.groupby("flight").size()
        assert (per_flight.reindex(flights.flight).to_numpy() == flights.steps.to_numpy()).all()
        assert set(steps["class"]) <= {"excellent", "mediocre", "poor"}
        assert steps[["x_m", "y_m", "z_m", "serving_rsrp_dbm"]].notna().all().all()
