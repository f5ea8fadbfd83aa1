"""`sage3d eval --agent ws:HOST:PORT` against a WebSocket policy server written with the
`websockets` package and openpi's own `openpi_client.msgpack_numpy` (PyPI `openpi-client`), from
the protocol: it behaves like openpi's `WebsocketPolicyServer` (metadata first on every
connection, `server_timing` added to every reply, an exception answered by a traceback text frame
and a close with 1011) and like GN0's WNM-3D server (`{"status": "reset successful"}` to a reset,
`nav_delta` replies (8, 3) float32 with 0-d arrays beside them). The server checks every request
it receives (endpoint order, uint8 HWC on a session's first query then THWC with one frame per
executed action, the session id, the instruction, the state) and the tests check what sage3d
scored (`RUN/episodes.jsonl`, `RUN/summary.json`).
"""

import json
import threading
import traceback

import numpy as np
import pytest
from conftest import few_vln_split

msgpack_numpy = pytest.importorskip("openpi_client.msgpack_numpy")
sync_server = pytest.importorskip("websockets.sync.server")
from websockets.exceptions import ConnectionClosed  # noqa: E402

STOP_ROW = [0.0, 0.0, 0.0]


class PolicyServer:
    """A policy server on 127.0.0.1 (port 0). `policy(session, n)` gives the reply of a
    session's n-th infer request (from 0, counted per session across reconnects) or raises;
    every received message is checked and recorded per session."""

    def __init__(self, policy, action_num=8, state=False):
        self.policy = policy
        self.action_num = action_num
        self.state = state
        self.lock = threading.Lock()
        self.violations = []
        self.sessions = {}  # session id -> list of (kind, shape) in arrival order
        self.infers = {}  # session id -> infer count
        self.last_reply_len = {}  # session id -> actions of the last reply (capped)
        self.fresh = {}  # connection -> True until its first infer
        self.server = sync_server.serve(self.handle, "127.0.0.1", 0, compression=None, max_size=None)
        self.port = self.server.socket.getsockname()[1]
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def violation(self, text):
        with self.lock:
            self.violations.append(text)

    def handle(self, ws):
        ws.send(msgpack_numpy.packb({"model_name": "test-policy", "input_format": "HWC/THWC uint8",
                                     "output_format": "nav_delta"}))
        first = True
        while True:
            try:
                message = ws.recv()
            except ConnectionClosed:
                return
            if isinstance(message, str):
                self.violation(f"a text frame from the client: {message[:80]}")
                return
            try:
                request = msgpack_numpy.unpackb(message)
                endpoint = request.get("endpoint")
                if endpoint == "reset":
                    first = True
                    ws.send(msgpack_numpy.packb({"status": "reset successful"}))
                    continue
                if endpoint != "infer":
                    self.violation(f"endpoint {endpoint!r}")
                    return
                reply = self.infer(request, first)
                first = False
                reply["server_timing"] = {"infer_ms": 1.0}
                ws.send(msgpack_numpy.packb(reply))
            except Exception:
                # openpi's WebsocketPolicyServer: the traceback as text, then close 1011.
                ws.send(traceback.format_exc())
                ws.close(1011, "Internal server error")
                return

    def infer(self, request, first):
        session = request.get("session_id")
        images = request.get("images")
        with self.lock:
            seen = self.sessions.setdefault(session, [])
            n = self.infers.get(session, 0)
            self.infers[session] = n + 1
            expect_t = self.last_reply_len.get(session)
        if not isinstance(images, np.ndarray) or images.dtype != np.uint8:
            self.violation(f"{session}: images are {type(images).__name__} {getattr(images, 'dtype', '')}")
        elif first:
            if images.ndim != 3 or images.shape[2] != 3:
                self.violation(f"{session}: the first query's images have shape {images.shape}, expected HWC")
        elif images.ndim != 4 or images.shape[3] != 3 or images.shape[0] != expect_t:
            self.violation(f"{session}: images of shape {images.shape}, expected THWC with T={expect_t}")
        if not isinstance(request.get("instruction"), str) or not request["instruction"]:
            self.violation(f"{session}: no instruction")
        pose = request.get("state.nav_pose")
        if self.state and (not isinstance(pose, np.ndarray) or pose.dtype != np.float32 or pose.shape != (3,)):
            self.violation(f"{session}: state.nav_pose is {pose!r}")
        if not self.state and pose is not None:
            self.violation(f"{session}: state.nav_pose sent without state=1")
        with self.lock:
            seen.append(("hwc" if first else "thwc", tuple(images.shape), request.get("instruction"),
                         None if pose is None else pose.tolist()))
        reply = self.policy(session, n)
        actions = np.asarray(reply["actions"])
        with self.lock:
            self.last_reply_len[session] = min(len(actions), self.action_num)
        return reply


def nav_delta(rows):
    """A WNM-3D reply: (N, 3) float32 rows in physical units, plus 0-d arrays."""
    rows = np.asarray(rows, dtype=np.float32)
    return {"action_type": "nav_delta", "actions": rows, "action.nav_delta": rows,
            "action.nav_delta_scaled": rows * 4.0, "inference_time": np.array(0.01, dtype=np.float32),
            "step": np.int64(3)}


def wnm3d(session, n):
    """Two chunks of 8 rows (0.1 m forward, 5 degrees left), then STOP rows."""
    if n < 2:
        return nav_delta([[0.1, 0.0, np.radians(5.0)]] * 8)
    return nav_delta([STOP_ROW] * 8)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, sage3d):
    return few_vln_split(sage3d, tmp_path_factory.mktemp("ws"))


def run_eval(sage3d, dataset, out, agent):
    scenes, data, _ = dataset
    proc = sage3d("--threads", 1, "eval", data, "--scenes", scenes, "--split", "few", "--agent", agent,
                  "--out", out, check=False)
    assert (out / "episodes.jsonl").exists(), proc.stderr
    records = {}
    for line in (out / "episodes.jsonl").read_text().splitlines():
        r = json.loads(line)
        records[r["episode_id"]] = r
    return proc, records, json.loads((out / "summary.json").read_text())


def test_wnm3d_like_server_episodes_complete_with_nav_delta_chunks(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    server = PolicyServer(wnm3d, action_num=4, state=True)
    proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", f"ws:127.0.0.1:{server.port}?actions=4&state=1")
    assert proc.returncode == 0, proc.stderr
    assert server.violations == []
    assert set(records) == set(instructions) and summary["failed"] == [] and summary["faults"] == {}
    for eid, rec in records.items():
        assert "faults" not in rec and "error" not in rec
        # 4 rows of each of two chunks, then STOP: 9 steps, each row one step.
        assert rec["termination"] == "stop"
        steps = rec["record"]["steps"]
        assert len(steps) == 9
        # Each row commands 0.1 m (what physics let through is the step's own business).
        assert all(s["commanded"] == pytest.approx(0.1, abs=1e-4) for s in steps[:8])
        seen = server.sessions[eid]
        assert [(kind, len(shape)) for kind, shape, _, _ in seen] == [("hwc", 3), ("thwc", 4), ("thwc", 4)]
        assert [shape[0] for _, shape, _, _ in seen[1:]] == [4, 4]
        assert all(instruction == instructions[eid] for _, _, instruction, _ in seen)
        # The state of the first query is the start pose (W frame).
        x, y, yaw = seen[0][3]
        assert yaw == pytest.approx(rec["record"]["start_yaw"], abs=1e-5)
        assert "server metadata" in " ".join(rec.get("notes", []))
    server.server.shutdown()


def test_a_discrete_stop_ends_the_episode(sage3d, dataset, tmp_path):
    server = PolicyServer(lambda session, n: {"action_type": "discrete", "actions": [1, 2, 0, 1]})
    proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", f"ws:127.0.0.1:{server.port}")
    assert proc.returncode == 0, proc.stderr
    assert server.violations == []
    for eid, rec in records.items():
        assert rec["termination"] == "stop"
        assert len(rec["record"]["steps"]) == 3
        assert len(server.sessions[eid]) == 1
    server.server.shutdown()


def test_a_server_that_raises_once_gives_a_recorded_fault_and_a_retry_not_a_move(sage3d, dataset, tmp_path):
    raised = []

    def policy(session, n):
        if n == 1 and not raised:
            raised.append(session)
            raise ValueError("boom in the policy")
        stop_at = 3 if session in raised else 2
        return {"action_type": "discrete", "actions": [0] if n >= stop_at else [1, 1]}

    server = PolicyServer(policy)
    proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", f"ws:127.0.0.1:{server.port}")
    assert proc.returncode == 0, proc.stderr
    assert server.violations == []
    assert len(raised) == 1 and summary["faults"] == {"server_error": 1}
    for eid, rec in records.items():
        actions = [s["commanded"] for s in rec["record"]["steps"]]
        if eid == raised[0]:
            # Query 0: 2 forward; query 1 raised (a fault, no step); the retry reconnected, reset
            # and sent the current frame as HWC (query 2: 2 forward); query 3: STOP.
            assert [(f["step"], f["attempt"], f["kind"], f["recovered"]) for f in rec["faults"]] == [
                (2, 1, "server_error", True)]
            assert "ValueError: boom in the policy" in rec["faults"][0]["message"]
            assert len(actions) == 5
            assert [kind for kind, *_ in server.sessions[eid]] == ["hwc", "thwc", "hwc", "thwc"]
        else:
            assert "faults" not in rec
            assert len(actions) == 5
        assert rec["termination"] == "stop"
    server.server.shutdown()


def test_the_python_api_takes_the_ws_agent_string(dataset, tmp_path):
    sage3d_py = pytest.importorskip("sage3d")
    scenes, data, instructions = dataset
    server = PolicyServer(lambda session, n: {"action_type": "discrete", "actions": [1, 0]})
    agent = f"ws:127.0.0.1:{server.port}?actions=2"
    sage3d_py.evaluate(str(data), scenes=str(scenes), agent=agent, out=str(tmp_path / "run"), split="few")
    run = json.loads((tmp_path / "run" / "sage3d_run.json").read_text())
    assert run["settings"]["agent"] == agent
    assert set(server.sessions) == set(instructions)
    assert server.violations == []
    server.server.shutdown()
