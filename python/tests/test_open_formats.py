"""The run directory's metrics read by TensorBoard's own reader."""

from __future__ import annotations

import json

from conftest import prerequisite


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
