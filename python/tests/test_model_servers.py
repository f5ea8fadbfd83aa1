"""`sage3d eval` against model servers written like the published SAGE-3D ones: a socket server
with struct '>Q' framing that decodes the base64 JPEGs with PIL, and an http.server `/vln_step`
endpoint answering NaVILA-style text. The servers script a navigator (move forward 75 cm, turn
left 30 degrees, stop) and record what they received: the instruction, the frame count and the
decoded frames, so the test checks the history grows and holds real, changing views."""

import base64
import hashlib
import http.server
import io
import json
import socket
import socketserver
import struct
import threading

import pytest
from conftest import few_vln_split
from PIL import Image

SCRIPT = [
    "The next action is move forward 75 cm.",
    "The next action is turn left 30 degrees.",
    "The next action is stop.",
]


class Navigator:
    """Decodes a request's frames and answers by the script, per episode (an episode's first
    request carries one frame)."""

    def __init__(self):
        self.requests = []
        self.lock = threading.Lock()

    def answer(self, images, instruction):
        frames = []
        for b64 in images:
            img = Image.open(io.BytesIO(base64.b64decode(b64)))
            assert img.format == "JPEG"
            frames.append((img.size, img.mode, hashlib.sha1(img.tobytes()).hexdigest()))
        with self.lock:
            self.requests.append({"instruction": instruction, "frames": frames})
            k = 0
            for r in reversed(self.requests):
                if len(r["frames"]) == 1:
                    break
                k += 1
            return SCRIPT[min(k, len(SCRIPT) - 1)]


def recv_exact(conn, n):
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        if not chunk:
            raise ConnectionError("client closed")
        data += chunk
    return data


def start_socket_server(nav):
    """The published socket server's loop: one request per connection, '>Q' length + JSON."""

    class Handler(socketserver.BaseRequestHandler):
        def handle(self):
            (length,) = struct.unpack(">Q", recv_exact(self.request, 8))
            req = json.loads(recv_exact(self.request, length).decode("utf-8"))
            text = nav.answer(req["images"], req["query"])
            reply = json.dumps({"status": "success", "result": text, "inference_time": 0.01}).encode("utf-8")
            self.request.sendall(struct.pack(">Q", len(reply)) + reply)

    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def start_http_server(nav):
    """The published HTTP server's /vln_step: JSON {images, instruction, current_yaw} in,
    {result: text} out."""

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_POST(self):
            if self.path != "/vln_step":
                self.send_error(404)
                return
            req = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
            assert req["current_yaw"] == 0.0
            body = json.dumps({"result": nav.answer(req["images"], req["instruction"])}).encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, sage3d):
    scenes, data, _ = few_vln_split(sage3d, tmp_path_factory.mktemp("servers"))
    return scenes, data


def run_eval(sage3d, dataset, tmp_path, agent, expect_failure=False):
    scenes, data = dataset
    out = tmp_path / "run"
    proc = sage3d("--threads", 1, "eval", data, "--scenes", scenes, "--split", "few", "--agent", agent, "--out", out,
                  check=not expect_failure)
    if expect_failure:
        assert proc.returncode != 0, "a run whose every episode failed must exit non-zero"
        assert "every episode of the run faulted" in proc.stderr, proc.stderr
    records = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    summary = json.loads((out / "summary.json").read_text())
    run = json.loads((out / "sage3d_run.json").read_text())
    return records, summary, run


def check(nav, records, summary, history):
    assert records and summary["failed"] == []
    instructions = set()
    for r in records:
        assert "error" not in r and "faults" not in r
        if r["task"] == "vln":
            # Three forward steps, two turns, STOP.
            assert r["termination"] == "stop"
            assert len(r["record"]["steps"]) == 6
            assert 0.0 <= r["metrics"]["tl"] <= 0.75 + 1e-6
    # Split the requests into episodes and check each one's history.
    episodes = []
    for req in nav.requests:
        if len(req["frames"]) == 1:
            episodes.append([])
        episodes[-1].append(req)
        instructions.add(req["instruction"])
        for size, mode, _ in req["frames"]:
            assert size == (224, 224) and mode == "RGB"
    assert len(episodes) == len(records)
    full = [e for e in episodes if len(e) == 3]
    assert len(full) == 3
    moved = 0
    for first, second, third in full:
        assert [len(first["frames"]), len(second["frames"]), len(third["frames"])] == [1, min(4, history), min(6, history)]
        # The history is the real recent frames, current last: not copies of the first frame.
        assert second["frames"][0] == first["frames"][0] or history < 4
        assert len({f[2] for f in third["frames"]}) > 1
        assert third["frames"][-1] != second["frames"][-1]
        assert third["frames"][-3] == second["frames"][-1]
        moved += second["frames"][-1] != first["frames"][-1]
    assert moved >= 1
    assert summary["overall"]["episodes"] == len(records)
    assert any(r["metrics"]["tl"] > 0.5 for r in records if r["task"] == "vln")


def test_socket_protocol_end_to_end(sage3d, dataset, tmp_path):
    nav = Navigator()
    server = start_socket_server(nav)
    try:
        port = server.server_address[1]
        records, summary, run = run_eval(sage3d, dataset, tmp_path, f"socket:127.0.0.1:{port}")
    finally:
        server.shutdown()
    assert run["settings"]["agent"] == f"socket:127.0.0.1:{port}"
    check(nav, records, summary, history=8)


def test_http_vln_step_end_to_end(sage3d, dataset, tmp_path):
    nav = Navigator()
    server = start_http_server(nav)
    try:
        port = server.server_address[1]
        records, summary, run = run_eval(sage3d, dataset, tmp_path, f"http:http://127.0.0.1:{port}?history=5")
    finally:
        server.shutdown()
    assert run["settings"]["agent"] == f"http:http://127.0.0.1:{port}/vln_step?history=5"
    check(nav, records, summary, history=5)


def test_a_dead_server_fails_each_episode_and_the_run_finishes(sage3d, dataset, tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    records, summary, _ = run_eval(sage3d, dataset, tmp_path, f"socket:127.0.0.1:{port}?retries=1&timeout=1",
                                   expect_failure=True)
    assert len(summary["failed"]) == len(records) > 0
    for r in records:
        assert f"127.0.0.1:{port}" in r["error"] and "after 2 attempts" in r["error"]
        assert [(f["step"], f["attempt"], f["kind"]) for f in r["faults"]] == [(0, 1, "transport"), (0, 2, "transport")]
    assert summary["failures"] == {"model_server": len(records)}
