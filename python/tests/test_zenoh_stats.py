"""The stats of a real distributed run read by the zenoh Python client alone: JSON published with
zenoh's encoding `application/json`, carrying the schema version, the weights version,
updates/s and drops (docs/distributed.md "Stats and control: JSON")."""

from __future__ import annotations

import json
import re
import subprocess
import threading
import time

from conftest import REPO, prerequisite

try:
    import zenoh
except ImportError:  # pragma: no cover - the prerequisite below says so
    zenoh = None

# The layout this test reads (common/src/jsonmsg.rs JSON_SCHEMA_VERSION).
SCHEMA = 1
RUN = "pytest-zenoh-stats"
ENDPOINT = re.compile(r"router on (tcp/127\.0\.0\.1:\d+)")


def _drain(stream, lines: list[str]) -> None:
    for line in stream:
        lines.append(line)


def _open_client(endpoint: str, deadline: float):
    """A zenoh client session of the run's router, retried while the learner starts."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    while True:
        try:
            return zenoh.open(conf)
        except zenoh.ZError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def test_a_python_zenoh_client_reads_a_runs_stats(dupac_bin, small_set, tmp_path):
    prerequisite(zenoh is not None, "the zenoh Python client (pip install eclipse-zenoh==1.10.2)")
    # 64 updates of the small scenario with stats every 0.2 s: a few seconds, dozens of messages.
    sets = [
        *small_set,
        f'distributed.run="{RUN}"',
        "distributed.stats_every_s=0.2",
        "train.total_timesteps=16384",
    ]
    proc = subprocess.Popen(
        [str(dupac_bin), "-q", "train", "--actors", "1", "--out", str(tmp_path / "run"),
         *[a for kv in sets for a in ("--set", kv)]],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    err: list[str] = []
    reader = threading.Thread(target=_drain, args=(proc.stderr, err), daemon=True)
    reader.start()
    deadline = time.monotonic() + 240
    samples: list[tuple[str, str, dict]] = []
    session = None
    try:
        endpoint = None
        while endpoint is None:
            found = [m.group(1) for line in err if (m := ENDPOINT.search(line))]
            endpoint = found[0] if found else None
            assert proc.poll() is None or endpoint, "dupac train exited early:\n" + "".join(err)
            assert time.monotonic() < deadline, "no endpoint printed:\n" + "".join(err)
            time.sleep(0.1)
        session = _open_client(endpoint, deadline)

        def on_sample(s) -> None:
            samples.append((str(s.key_expr), str(s.encoding), json.loads(s.payload.to_bytes())))

        # Kept until the end: a subscriber is undeclared when it is dropped.
        sub = session.declare_subscriber(f"dupac/{RUN}/stats/**", on_sample)

        def done() -> bool:
            return any(m.get("kind") == "learner_stats" and m["done"] for _, _, m in samples)

        while not done() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        code = proc.wait(timeout=max(1.0, deadline - time.monotonic()))
        assert code == 0, "dupac train failed:\n" + "".join(err)
        sub.undeclare()
    finally:
        if session is not None:
            session.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()

    assert samples, "no stats received:\n" + "".join(err)
    for key, encoding, msg in samples:
        assert encoding == "application/json", (key, encoding)
        assert msg["schema"] == SCHEMA, (key, msg)
    learner = [m for k, _, m in samples if k == f"dupac/{RUN}/stats/learner"]
    actors = [m for k, _, m in samples if k.startswith(f"dupac/{RUN}/stats/actor/")]
    assert learner and actors, [k for k, _, _ in samples]
    assert all(m["kind"] == "learner_stats" for m in learner)
    assert all(m["kind"] == "actor_stats" for m in actors)
    last = learner[-1]
    # The weights version, updates/s and drops, as the learner reported them at the end.
    assert last["done"] is True
    assert last["update"] == last["total_updates"] == last["header"]["policy_version"] > 0
    assert last["header"]["run_id"] == RUN
    assert isinstance(last["updates_per_s"], float) and last["updates_per_s"] >= 0
    assert any(m["updates_per_s"] > 0 for m in learner)
    assert isinstance(last["drops"], dict)
    assert all(isinstance(v, int) and v >= 0 for v in last["drops"].values())
    assert last["accepted_chunks"] > 0
    assert [a["actor"] for a in last["actors"]] == [0]
    # The learner's stats are numbered in order; actors report the version they act with.
    seqs = [m["header"]["seq"] for m in learner]
    assert seqs == sorted(seqs), seqs
    assert max(m["header"]["policy_version"] for m in actors) > 0
    assert all(m["env_steps"] >= 0 and m["num_envs"] > 0 for m in actors)
