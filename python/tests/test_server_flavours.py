"""`sage3d eval` against fakes of the three published SAGE-3D model servers (`?server=navila`,
`?server=navid`, `?server=mllm`), written from their documented protocol: TCP on loopback, one
request per connection (8-byte big-endian length + UTF-8 JSON `{"images": [base64 JPEG, ...],
"query": instruction}`, the reply in the same framing), accepted one connection at a time as the
published servers do (`listen(1)`, a sequential accept loop). Each fake decodes the JPEGs with
PIL, keeps a hash of every decoded frame and records what it received and any breach of its
protocol; the tests assert both that and what sage3d scored (`RUN/episodes.jsonl`,
`RUN/summary.json`, the exit status).

- NaVILA: 8 frames per request, the real frames oldest first, padded at the front with copies of
  the episode's first frame; free-text replies ("move forward 100 cm" = 4 steps, carried out in
  full; "turn left" = 30 degrees); "Error processing request: ..." is a server_error fault.
- NaVid: `{"action": "reset"}` before each episode, one frame per step request, velocity replies;
  the server keeps ONE history, so episodes must not interleave even with `--threads 2`; a model
  text the server cannot read (it substitutes a random action) is a `substituted` fault; its
  exception reply (`parsed_from: "error"`, `stop: true`) is a server_error fault, never a STOP.
- MLLM: the current frame first (then earlier frames newest first with `history=3`); replies
  `{"status": "success", "result": "MOVE_FORWARD" | ...}`; `"status": "error"` is a server_error
  fault, never a forward step.
- A run whose every episode fails exits non-zero; `--strict` makes one failed episode do so.
"""

import base64
import hashlib
import io
import json
import math
import random
import re
import socket
import struct
import threading

import pytest
from conftest import few_vln_split
from PIL import Image

FORWARD_M = 0.25
TURN = math.radians(15)
SIZE = (224, 224)


# ---------------------------------------------------------------------------------------------
# Framing and the sequential server loop of the published servers
# ---------------------------------------------------------------------------------------------


def recv_exact(conn, n):
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        if not chunk:
            raise ConnectionError(f"client closed after {len(data)} of {n} bytes")
        data += chunk
    return data


def read_message(conn):
    (length,) = struct.unpack(">Q", recv_exact(conn, 8))
    return json.loads(recv_exact(conn, length).decode("utf-8"))


def send_message(conn, value):
    payload = json.dumps(value).encode("utf-8")
    conn.sendall(struct.pack(">Q", len(payload)) + payload)


def decode_frames(images, violations):
    """The request's JPEGs decoded with PIL: the sha1 of each decoded frame's pixels."""
    hashes = []
    for b64 in images:
        img = Image.open(io.BytesIO(base64.b64decode(b64)))
        if img.format != "JPEG":
            violations.append(f"expected a JPEG frame, got {img.format}")
        img.load()
        if img.size != SIZE or img.mode != "RGB":
            violations.append(f"expected a {SIZE} RGB frame, got {img.size} {img.mode}")
        hashes.append(hashlib.sha1(img.tobytes()).hexdigest())
    return hashes


class SequentialServer:
    """One plain listening socket (127.0.0.1, port 0, listen(1)) and one thread that accepts a
    connection, reads one request, replies with `handle(request)` and closes, then accepts the
    next: connections are served one at a time, as the published servers serve them."""

    def __init__(self, handle):
        self.handle = handle
        self.violations = []
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(1)
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _loop(self):
        while not self.stopped.is_set():
            try:
                conn, _ = self.sock.accept()
            except socket.timeout:
                continue
            except OSError:
                break
            with conn:
                conn.settimeout(30)
                try:
                    request = read_message(conn)
                    send_message(conn, self.handle(request))
                except Exception as e:  # a broken exchange is the client's fault here: record it
                    self.violations.append(f"exchange failed: {type(e).__name__}: {e}")

    def close(self):
        self.stopped.set()
        self.thread.join(5)
        self.sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# ---------------------------------------------------------------------------------------------
# The fakes
# ---------------------------------------------------------------------------------------------

NAVILA_SCRIPT = [
    "The next action is move forward 100 cm.",
    "The next action is turn left.",
    "The next action is stop.",
]
NAVILA_FRAMES = 8


class NaVILA:
    """The NaVILA server: its model reads exactly 8 frames (fewer raise IndexError, which the
    server answers as "Error processing request: list index out of range"); it answers free text
    by a per-episode script. `error_at` answers that request (0-based, in arrival order) with a
    CUDA error; `always_error` answers every request with an error; `fail_query` answers every
    request for that instruction with an error."""

    def __init__(self, error_at=None, always_error=False, fail_query=None):
        self.error_at = error_at
        self.always_error = always_error
        self.fail_query = fail_query
        self.requests = []
        self.violations = []
        self.progress = {}  # instruction -> index in the script of its episode's next answer

    def __call__(self, req):
        images, query = req.get("images"), req.get("query")
        if not isinstance(images, list) or not isinstance(query, str):
            self.violations.append(f"expected images (list) and query (str), got keys {sorted(req)}")
            return "Error processing request: bad request"
        frames = decode_frames(images, self.violations)
        entry = {"query": query, "frames": frames, "count": len(images), "reply": None, "script": None}
        index = len(self.requests)
        self.requests.append(entry)
        if len(images) < NAVILA_FRAMES:
            self.violations.append(f"request {index}: expected {NAVILA_FRAMES} frames, got {len(images)}")
            entry["reply"] = "Error processing request: list index out of range"
        elif len(images) > NAVILA_FRAMES:
            self.violations.append(f"request {index}: expected {NAVILA_FRAMES} frames, got {len(images)}")
            entry["reply"] = "Error processing request: too many frames"
        elif self.always_error or query == self.fail_query:
            entry["reply"] = "Error processing request: boom"
        elif index == self.error_at:
            entry["reply"] = "Error processing request: CUDA out of memory"
        else:
            k = self.progress.get(query, 0)
            if (k == 0) != (len(set(frames)) == 1):
                self.violations.append(
                    f"request {index}: expected all 8 frames identical exactly on an episode's first "
                    f"request (script position {k}), got {len(set(frames))} distinct frames"
                )
            entry["script"] = k
            entry["reply"] = NAVILA_SCRIPT[k]
            self.progress[query] = (k + 1) % len(NAVILA_SCRIPT)
        return entry["reply"]

    def episode_requests(self, query):
        """The requests of one instruction's episode that got a script answer."""
        return [r for r in self.requests if r["query"] == query and r["script"] is not None]


NAVID_SCRIPT = [
    "move forward 75 cm",  # 3 forward steps: replies 2 and 3 are "Pending action"
    "I am not sure",  # unreadable: the server substitutes a random action
    "turn right 30 degrees",  # one right action = two 15-degree right turns
    "stop",
]
NAVID_VELOCITY = {
    "STOP": {"vx": 0.0, "vy": 0.0, "yaw_rate": 0.0, "duration_s": 0.0, "stop": True},
    "FORWARD": {"vx": 0.25, "vy": 0.0, "yaw_rate": 0.0, "duration_s": 1.0, "stop": False},
    "LEFT": {"vx": 0.0, "vy": 0.0, "yaw_rate": math.radians(30), "duration_s": 1.0, "stop": False},
    "RIGHT": {"vx": 0.0, "vy": 0.0, "yaw_rate": -math.radians(30), "duration_s": 1.0, "stop": False},
}
NAVID_EXCEPTION = {
    "vx": 0.0,
    "vy": 0.0,
    "yaw_rate": 0.0,
    "duration_s": 0.0,
    "stop": True,
    "raw_response": "Error: boom",
    "parsed_from": "error",
    "status": "success",
    "text_response": "Error: boom",
}


def navid_read(text):
    """The NaVid server's reading of its model's text: a list of actions, or None when it
    cannot read it (the server then substitutes a random action)."""
    t = text.lower()
    numbers = re.findall(r"\d+", t)
    n = int(numbers[0]) if numbers else None
    if "stop" in t:
        return ["STOP"]
    if "forward" in t:
        kind, count = "FORWARD", min(3, int((50 if n is None else n) / 25))
    elif "left" in t:
        kind, count = "LEFT", min(3, int((30 if n is None else n) / 30))
    elif "right" in t:
        kind, count = "RIGHT", min(3, int((30 if n is None else n) / 30))
    else:
        return None
    if count <= 0:
        return None
    return [kind] * count


class NaVid:
    """The NaVid server: ONE history per server process, cleared by `{"action": "reset"}`;
    pending actions from one model output are answered one per request ("Pending action").
    `exception_at` = (episode number by reset order, 1-based; step request index in that
    episode, 0-based) answers that request with the server's exception reply."""

    def __init__(self, exception_at=None, seed=0):
        self.exception_at = exception_at
        self.rng = random.Random(seed)
        self.history = []
        self.pending = []
        self.model_calls = 0
        self.resets = 0
        self.episode_query = None
        self.step_in_episode = 0
        self.log = []  # {"kind": "reset"} or a step request's entry, in arrival order
        self.violations = []
        self.substitutes = []

    def __call__(self, req):
        if "action" in req:
            if req != {"action": "reset"}:
                self.violations.append(f'expected exactly {{"action": "reset"}}, got {req}')
            self.history.clear()
            self.pending.clear()
            self.model_calls = 0
            self.resets += 1
            self.episode_query = None
            self.step_in_episode = 0
            self.log.append({"kind": "reset"})
            return {"status": "reset_complete"}
        images, query = req.get("images"), req.get("query")
        if not isinstance(images, list) or not images or not isinstance(query, str):
            self.violations.append(f"expected images (non-empty list) and query (str), got {sorted(req)}")
            return NAVID_EXCEPTION
        frames = decode_frames(images, self.violations)
        index = len(self.log)
        if len(images) != 1:
            self.violations.append(f"log entry {index}: expected 1 image per step request, got {len(images)}")
        if self.resets == 0:
            self.violations.append(f"log entry {index}: a step request before any reset")
        if self.episode_query is not None and query != self.episode_query:
            self.violations.append(
                f"log entry {index}: the query changed without a reset (episodes interleaved): "
                f"{self.episode_query!r} then {query!r}"
            )
        self.episode_query = query
        entry = {"kind": "step", "query": query, "frame": frames[-1], "count": len(images),
                 "episode": self.resets, "step_request": self.step_in_episode}
        self.log.append(entry)
        self.step_in_episode += 1
        if self.exception_at == (entry["episode"], entry["step_request"]):
            entry["reply"] = NAVID_EXCEPTION
            return NAVID_EXCEPTION
        self.history.append(frames[-1])
        entry["history_len"] = len(self.history)
        if entry["step_request"] == 0 and len(self.history) != 1:
            self.violations.append(
                f"log entry {index}: expected a history of 1 frame at an episode's first step "
                f"request (after its reset), got {len(self.history)}"
            )
        if self.pending:
            action, raw = self.pending.pop(0), "Pending action"
        else:
            raw = NAVID_SCRIPT[min(self.model_calls, len(NAVID_SCRIPT) - 1)]
            self.model_calls += 1
            actions = navid_read(raw)
            if actions is None:
                actions = [self.rng.choice(["STOP", "FORWARD", "LEFT", "RIGHT"])]
                self.substitutes.append((entry["episode"], entry["step_request"], actions[0]))
            action, self.pending = actions[0], actions[1:]
        reply = dict(NAVID_VELOCITY[action], raw_response=raw, parsed_from="navid",
                     status="success", text_response=raw)
        entry["reply"] = reply
        return reply


MLLM_SCRIPT = ["MOVE_FORWARD", "MOVE_FORWARD", "TURN_LEFT", "STOP"]


class MLLM:
    """The MLLM server: decides on images[0] (the current frame) only, by a per-episode script.
    `error_at` answers that request (0-based, in arrival order) with the error status."""

    def __init__(self, error_at=None):
        self.error_at = error_at
        self.requests = []
        self.violations = []
        self.progress = {}

    def __call__(self, req):
        images, query = req.get("images"), req.get("query")
        if not isinstance(images, list) or not images or not isinstance(query, str):
            self.violations.append(f"expected images (non-empty list) and query (str), got {sorted(req)}")
            return {"status": "error", "message": "VLN query failed: bad request", "result": "MOVE_FORWARD"}
        frames = decode_frames(images, self.violations)
        entry = {"query": query, "current": frames[0], "frames": frames, "script": None}
        index = len(self.requests)
        self.requests.append(entry)
        if index == self.error_at:
            entry["reply"] = {"status": "error", "message": "VLN query failed: CUDA out of memory",
                              "result": "MOVE_FORWARD"}
            return entry["reply"]
        k = self.progress.get(query, 0)
        self.progress[query] = (k + 1) % len(MLLM_SCRIPT)
        entry["script"] = k
        entry["reply"] = {"status": "success", "result": MLLM_SCRIPT[k], "inference_time": 0.01}
        return entry["reply"]

    def episode_requests(self, query):
        return [r for r in self.requests if r["query"] == query and r["script"] is not None]


# ---------------------------------------------------------------------------------------------
# The dataset and the run
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, sage3d):
    """(scenes, data, {episode_id: instruction}) of the `few` split."""
    return few_vln_split(sage3d, tmp_path_factory.mktemp("flavours"))


def run_eval(sage3d, dataset, out, agent, threads=1, extra=()):
    """Runs `sage3d eval` on the `few` split; returns (process, {id: record}, summary)."""
    scenes, data, _ = dataset
    proc = sage3d("--threads", threads, "eval", data, "--scenes", scenes, "--split", "few",
                  "--agent", agent, "--out", out, *extra, check=False)
    episodes, summary = out / "episodes.jsonl", out / "summary.json"
    assert episodes.exists() and summary.exists(), (
        f"expected {episodes} and {summary} to be written (exit {proc.returncode}):\n{proc.stderr}"
    )
    records = {}
    for line in episodes.read_text().splitlines():
        r = json.loads(line)
        records[r["episode_id"]] = r
    return proc, records, json.loads(summary.read_text())


def assert_ran(proc):
    assert proc.returncode == 0, f"expected sage3d eval to exit 0, got {proc.returncode}:\n{proc.stderr}"


def wrap(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi


def assert_scored(rec, actions):
    """The record holds exactly `actions` (F forward, L / R a 15-degree turn, S STOP) as its
    steps, ended by STOP: commanded translation and heading change step by step."""
    eid = rec["episode_id"]
    assert "error" not in rec, f"{eid}: expected a scored episode, got error {rec.get('error')!r}"
    assert rec.get("termination") == "stop", f"{eid}: expected termination 'stop', got {rec.get('termination')!r}"
    assert rec["record"]["stop_called"] is True, f"{eid}: expected stop_called true"
    steps = rec["record"]["steps"]
    got = len(steps)
    assert got == len(actions), f"{eid}: expected {len(actions)} steps ({''.join(actions)}), got {got}"
    yaw = rec["record"]["start_yaw"]
    for i, (step, a) in enumerate(zip(steps, actions)):
        commanded = FORWARD_M if a == "F" else 0.0
        assert step["commanded"] == pytest.approx(commanded, abs=1e-6), (
            f"{eid} step {i} ({a}): expected commanded {commanded} m, got {step['commanded']}"
        )
        turn = {"L": TURN, "R": -TURN}.get(a, 0.0)
        assert wrap(step["yaw"] - yaw) == pytest.approx(turn, abs=1e-3), (
            f"{eid} step {i} ({a}): expected a heading change of {math.degrees(turn):.0f} deg, "
            f"got {math.degrees(wrap(step['yaw'] - yaw)):.2f} deg"
        )
        yaw = step["yaw"]


def fault_keys(rec):
    return [(f["step"], f["attempt"], f["kind"]) for f in rec.get("faults", [])]


def assert_one_server_error(records, summary, hit_id, step, says):
    """Episode `hit_id` has exactly one server_error fault (at `step`, first attempt, its message
    holding `says`), the others none; the run counts that one fault and no failure."""
    for eid, rec in records.items():
        if eid == hit_id:
            assert fault_keys(rec) == [(step, 1, "server_error")], (
                f"{eid}: expected one server_error fault at step {step}, attempt 1, got {rec.get('faults')}"
            )
            assert says in rec["faults"][0]["message"], (
                f"{eid}: expected the fault message to carry {says!r}, got {rec['faults'][0]['message']!r}"
            )
        else:
            assert "faults" not in rec, f"{eid}: expected no faults, got {rec.get('faults')}"
    assert summary["faults"] == {"server_error": 1}, f"expected summary faults {{'server_error': 1}}, got {summary['faults']}"
    assert summary["failed"] == [] and summary["failures"] == {}, (
        f"expected no failed episodes, got {summary['failed']} / {summary['failures']}"
    )


def moved(before, after):
    return math.dist(before[:2], after[:2]) > 0.05


def positions(rec):
    """Where the agent stood before each step, then after the last."""
    steps = rec["record"]["steps"]
    return [rec["record"]["start"]] + [s["position"] for s in steps]


# ---------------------------------------------------------------------------------------------
# NaVILA
# ---------------------------------------------------------------------------------------------

NAVILA_ACTIONS = "FFFFLLS"  # move forward 100 cm (4 steps), turn left (30 deg = 2 turns), stop


def check_navila_frames(nav, rec, query):
    """The three answered requests of an episode: 8 frames each, its real frames oldest first,
    current last, padded at the front with copies of its first frame."""
    eid = rec["episode_id"]
    reqs = nav.episode_requests(query)
    assert [r["script"] for r in reqs] == [0, 1, 2], (
        f"{eid}: expected 3 answered requests (forward, turn, stop), got script positions "
        f"{[r['script'] for r in reqs]}"
    )
    r1, r2, r3 = (r["frames"] for r in reqs)
    assert [len(r1), len(r2), len(r3)] == [8, 8, 8], f"{eid}: expected 8 frames per request"
    o0 = r1[0]
    assert r1 == [o0] * 8, f"{eid}: expected the first request to be 8 copies of the first frame"
    # After 4 forward steps: 5 real frames (o0..o4) padded with 3 copies of o0 at the front.
    assert r2[:4] == [o0] * 4, f"{eid}: expected request 2 to start with 3 copies of the first frame then the first frame"
    # After 2 turns: 7 real frames (o0..o6) padded with 1 copy of o0.
    assert r3[:2] == [o0] * 2, f"{eid}: expected request 3 to start with 1 copy of the first frame then the first frame"
    assert r3[2:6] == r2[4:8], f"{eid}: expected request 3's frames 3-6 to be request 2's last 4 (o1..o4)"
    frames = [o0] + r2[4:8] + r3[6:8]  # o0 .. o6, one per observation
    pos = positions(rec)
    for k in range(1, 5):  # the forward steps: a view from another place is another frame
        if moved(pos[k - 1], pos[k]):
            assert frames[k] != frames[k - 1], (
                f"{eid}: expected the frame after forward step {k} (the agent moved) to differ "
                "from the one before: the history must hold the real recent frames"
            )


def test_navila_flavour_sends_8_padded_frames_and_carries_out_long_replies(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    nav = NaVILA()
    with SequentialServer(nav) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=navila&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent)
    assert_ran(proc)
    assert server.violations == [], f"expected clean exchanges, got {server.violations}"
    assert nav.violations == [], f"expected no protocol violations at the NaVILA fake, got {nav.violations}"
    assert sorted(records) == sorted(instructions), f"expected a record per episode, got {sorted(records)}"
    assert len(nav.requests) == 9, f"expected 3 requests per episode (9), got {len(nav.requests)}"
    for eid, rec in records.items():
        assert "faults" not in rec, f"{eid}: expected no faults, got {rec.get('faults')}"
        assert_scored(rec, NAVILA_ACTIONS)
        check_navila_frames(nav, rec, instructions[eid])
    assert summary["failed"] == [], f"expected no failed episodes, got {summary['failed']}"
    assert summary["faults"] == {}, f"expected summary faults {{}}, got {summary['faults']}"
    assert summary["failures"] == {}, f"expected summary failures {{}}, got {summary['failures']}"


def test_navila_error_reply_is_a_server_error_fault_and_retried(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    nav = NaVILA(error_at=1)  # the first episode's second request (after its 4 forward steps)
    with SequentialServer(nav) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=navila&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent)
    assert_ran(proc)
    assert server.violations == [] and nav.violations == [], (
        f"expected no protocol violations, got {server.violations + nav.violations}"
    )
    failed_req, retry = nav.requests[1], nav.requests[2]
    assert "CUDA" in failed_req["reply"], "expected the second request to get the injected error"
    assert retry["query"] == failed_req["query"] and retry["frames"] == failed_req["frames"], (
        "expected the retry to resend the same frames and instruction"
    )
    hit = [eid for eid, q in instructions.items() if q == failed_req["query"]]
    assert len(hit) == 1
    for eid, rec in records.items():
        assert_scored(rec, NAVILA_ACTIONS)
        check_navila_frames(nav, rec, instructions[eid])
    assert_one_server_error(records, summary, hit[0], 4, "CUDA out of memory")


# ---------------------------------------------------------------------------------------------
# NaVid
# ---------------------------------------------------------------------------------------------

NAVID_ACTIONS = "FFFRRS"  # 3 forward (one model output), 2 right turns (one RIGHT action), STOP


def check_navid_log(navid, instructions, step_requests):
    """Reset, then the step requests of one episode, three times: never interleaved."""
    assert navid.violations == [], f"expected no protocol violations at the NaVid fake, got {navid.violations}"
    assert navid.resets == 3, f"expected one reset per episode (3), got {navid.resets}"
    episodes = []
    for entry in navid.log:
        if entry["kind"] == "reset":
            episodes.append([])
        else:
            assert episodes, "expected a reset before the first step request"
            episodes[-1].append(entry)
    assert [len(e) for e in episodes] == step_requests, (
        f"expected step requests per episode {step_requests}, got {[len(e) for e in episodes]}"
    )
    queries = [e[0]["query"] for e in episodes]
    assert sorted(queries) == sorted(instructions.values()), (
        f"expected each episode's instruction once, got {queries}"
    )
    for e in episodes:
        assert {s["query"] for s in e} == {e[0]["query"]}, "expected one instruction between two resets"
        assert all(s["count"] == 1 for s in e), "expected exactly 1 image per step request"
    return episodes


def test_navid_flavour_resets_sends_one_frame_and_flags_substituted_actions(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    navid = NaVid()
    with SequentialServer(navid) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=navid&timeout=30"
        # Two threads: the navid flavour must still run the episodes one at a time.
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent, threads=2)
    assert_ran(proc)
    assert server.violations == [], f"expected clean exchanges, got {server.violations}"
    # Forward, 2 pending forwards, unreadable (substituted), its retry (right), stop.
    episodes = check_navid_log(navid, instructions, [6, 6, 6])
    expected_raws = [NAVID_SCRIPT[0], "Pending action", "Pending action", NAVID_SCRIPT[1], NAVID_SCRIPT[2], NAVID_SCRIPT[3]]
    for e in episodes:
        raws = [s["reply"]["raw_response"] for s in e]
        assert raws == expected_raws, f"expected the fake's replies {expected_raws}, got {raws}"
        assert e[4]["frame"] == e[3]["frame"], "expected the retry after the substituted action to resend the same frame"
    assert len(navid.substitutes) == 3, f"expected one substituted action per episode, got {navid.substitutes}"
    assert sorted(records) == sorted(instructions), f"expected a record per episode, got {sorted(records)}"
    for eid, rec in records.items():
        assert_scored(rec, NAVID_ACTIONS)
        assert fault_keys(rec) == [(3, 1, "substituted")], (
            f"{eid}: expected one substituted fault at step 3, attempt 1, got {rec.get('faults')}"
        )
        pos = positions(rec)
        ep = next(e for e in episodes if e[0]["query"] == instructions[eid])
        for k in range(1, 4):
            if moved(pos[k - 1], pos[k]):
                assert ep[k]["frame"] != ep[k - 1]["frame"], (
                    f"{eid}: expected step request {k} to carry the frame after forward step {k} "
                    "(the agent moved), not the one before"
                )
    assert summary["faults"] == {"substituted": 3}, f"expected summary faults {{'substituted': 3}}, got {summary['faults']}"
    assert summary["failed"] == [] and summary["failures"] == {}, (
        f"expected no failed episodes, got {summary['failed']} / {summary['failures']}"
    )


def test_navid_exception_reply_is_a_server_error_not_a_stop(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    navid = NaVid(exception_at=(2, 1))  # the second episode's second step request (step 1)
    with SequentialServer(navid) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=navid&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent)
    assert_ran(proc)
    assert server.violations == [], f"expected clean exchanges, got {server.violations}"
    episodes = check_navid_log(navid, instructions, [6, 7, 6])
    hit_query = episodes[1][1]["query"]
    assert episodes[1][1]["reply"] is NAVID_EXCEPTION, "expected the injected exception reply"
    assert episodes[1][2]["frame"] == episodes[1][1]["frame"], "expected the retry to resend the same frame"
    for eid, rec in records.items():
        # The episode went on after the exception reply: it did not end (STOP) at step 1.
        assert_scored(rec, NAVID_ACTIONS)
        if instructions[eid] == hit_query:
            assert fault_keys(rec) == [(1, 1, "server_error"), (3, 1, "substituted")], (
                f"{eid}: expected a server_error fault at step 1 then a substituted one at step 3, "
                f"got {rec.get('faults')}"
            )
            assert "boom" in rec["faults"][0]["message"], (
                f"{eid}: expected the fault message to carry the server's error, got {rec['faults'][0]['message']!r}"
            )
        else:
            assert fault_keys(rec) == [(3, 1, "substituted")], (
                f"{eid}: expected one substituted fault at step 3, got {rec.get('faults')}"
            )
    assert summary["faults"] == {"server_error": 1, "substituted": 3}, (
        f"expected summary faults {{'server_error': 1, 'substituted': 3}}, got {summary['faults']}"
    )
    assert summary["failed"] == [] and summary["failures"] == {}, (
        f"expected no failed episodes, got {summary['failed']} / {summary['failures']}"
    )


def test_navid_reading_rule_of_the_fake():
    """The fake reads its model's text as the published server does."""
    assert navid_read("move forward 75 cm") == ["FORWARD"] * 3
    assert navid_read("move forward 100 cm") == ["FORWARD"] * 3
    assert navid_read("go forward") == ["FORWARD"] * 2
    assert navid_read("move forward 10 cm") is None
    assert navid_read("turn right 30 degrees") == ["RIGHT"]
    assert navid_read("turn left 90 degrees") == ["LEFT"] * 3
    assert navid_read("Stop here") == ["STOP"]
    assert navid_read("I am not sure") is None


# ---------------------------------------------------------------------------------------------
# MLLM
# ---------------------------------------------------------------------------------------------

MLLM_ACTIONS = "FFLLS"  # MOVE_FORWARD, MOVE_FORWARD, TURN_LEFT (30 deg = 2 turns), STOP


def test_mllm_flavour_sends_the_current_frame_alone_and_error_status_is_a_fault(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    mllm = MLLM(error_at=1)  # the first episode's second request (step 1)
    with SequentialServer(mllm) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=mllm&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent)
    assert_ran(proc)
    assert server.violations == [] and mllm.violations == [], (
        f"expected no protocol violations, got {server.violations + mllm.violations}"
    )
    assert len(mllm.requests) == 13, f"expected 4 requests per episode plus one retry (13), got {len(mllm.requests)}"
    assert all(len(r["frames"]) == 1 for r in mllm.requests), (
        f"expected 1 frame per request by default, got {[len(r['frames']) for r in mllm.requests]}"
    )
    failed_req, retry = mllm.requests[1], mllm.requests[2]
    assert retry["query"] == failed_req["query"] and retry["frames"] == failed_req["frames"], (
        "expected the retry to resend the same frame and instruction"
    )
    for eid, rec in records.items():
        # The error reply carried result MOVE_FORWARD: it must not have been taken as a step.
        assert_scored(rec, MLLM_ACTIONS)
        reqs = mllm.episode_requests(instructions[eid])
        assert [r["script"] for r in reqs] == [0, 1, 2, 3], f"{eid}: expected 4 answered requests"
        pos = positions(rec)
        for k in (1, 2):
            if moved(pos[k - 1], pos[k]):
                assert reqs[k]["current"] != reqs[k - 1]["current"], (
                    f"{eid}: expected images[0] to change after MOVE_FORWARD {k} (the agent moved)"
                )
    hit = next(eid for eid, q in instructions.items() if q == failed_req["query"])
    assert_one_server_error(records, summary, hit, 1, "VLN query failed")


def test_mllm_flavour_history_sends_current_frame_first(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    mllm = MLLM()
    with SequentialServer(mllm) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=mllm&history=3&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, tmp_path / "run", agent)
    assert_ran(proc)
    assert server.violations == [] and mllm.violations == [], (
        f"expected no protocol violations, got {server.violations + mllm.violations}"
    )
    assert len(mllm.requests) == 12, f"expected 4 requests per episode (12), got {len(mllm.requests)}"
    for eid, rec in records.items():
        assert_scored(rec, MLLM_ACTIONS)
        assert "faults" not in rec, f"{eid}: expected no faults, got {rec.get('faults')}"
        reqs = mllm.episode_requests(instructions[eid])
        assert [r["script"] for r in reqs] == [0, 1, 2, 3], f"{eid}: expected 4 answered requests"
        r1, r2, r3, r4 = (r["frames"] for r in reqs)
        assert [len(r1), len(r2), len(r3), len(r4)] == [1, 2, 3, 3], (
            f"{eid}: expected 1, 2, 3, 3 frames (the frames there are, at most 3), "
            f"got {[len(r1), len(r2), len(r3), len(r4)]}"
        )
        # Observations o0 (start), o1, o2 (after the forward steps), o3, o4 (after the turns).
        o0, o1, o2 = r1[0], r2[0], r3[0]
        assert r2 == [o1, o0], f"{eid}: expected request 2 = [current, previous] (its images[1] = request 1's images[0])"
        assert r3 == [o2, o1, o0], f"{eid}: expected request 3 = [current, previous, the one before], newest first"
        assert r4[2] == o2, f"{eid}: expected request 4's oldest frame to be request 3's current frame (two turns between)"
        pos = positions(rec)
        for k, (before, after) in ((1, (o0, o1)), (2, (o1, o2))):
            if moved(pos[k - 1], pos[k]):
                assert before != after, f"{eid}: expected images[0] to change after MOVE_FORWARD {k} (the agent moved)"
    assert summary["faults"] == {} and summary["failed"] == [] and summary["failures"] == {}, (
        f"expected no faults or failures, got {summary['faults']} / {summary['failed']} / {summary['failures']}"
    )


# ---------------------------------------------------------------------------------------------
# Failures and the exit status
# ---------------------------------------------------------------------------------------------


def test_a_run_whose_every_episode_fails_exits_non_zero(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    nav = NaVILA(always_error=True)
    out = tmp_path / "run"
    with SequentialServer(nav) as server:
        agent = f"socket:127.0.0.1:{server.port}?server=navila&retries=1&timeout=30"
        proc, records, summary = run_eval(sage3d, dataset, out, agent)
    assert proc.returncode != 0, f"expected a non-zero exit when every episode failed, got 0:\n{proc.stdout}"
    assert (out / "summary.json").exists() and (out / "episodes.jsonl").exists(), "expected the run's files written"
    assert server.violations == [] and nav.violations == [], (
        f"expected no protocol violations, got {server.violations + nav.violations}"
    )
    assert len(nav.requests) == 6, f"expected 2 attempts per episode (6 requests), got {len(nav.requests)}"
    assert sorted(records) == sorted(instructions), f"expected a record per episode, got {sorted(records)}"
    for eid, rec in records.items():
        assert isinstance(rec.get("error"), str) and rec["error"], f"{eid}: expected an error message"
        assert f"127.0.0.1:{server.port}" in rec["error"], f"{eid}: expected the error to name the server, got {rec['error']!r}"
        assert rec.get("failure") == "model_server", f"{eid}: expected failure 'model_server', got {rec.get('failure')!r}"
        for key in ("metrics", "record", "termination"):
            assert key not in rec, f"{eid}: expected no {key} on a failed episode"
        assert fault_keys(rec) == [(0, 1, "server_error"), (0, 2, "server_error")], (
            f"{eid}: expected 2 server_error faults at step 0 (attempts 1, 2), got {rec.get('faults')}"
        )
        assert all("boom" in f["message"] for f in rec["faults"]), f"{eid}: expected the server's error in the faults"
    assert sorted(summary["failed"]) == sorted(instructions), f"expected every episode failed, got {summary['failed']}"
    assert summary["failures"] == {"model_server": 3}, f"expected failures {{'model_server': 3}}, got {summary['failures']}"
    assert summary["faults"] == {"server_error": 6}, f"expected faults {{'server_error': 6}}, got {summary['faults']}"


def test_strict_makes_one_failed_episode_fail_the_run(sage3d, dataset, tmp_path):
    _, _, instructions = dataset
    bad_id = sorted(instructions)[1]
    good = sorted(set(instructions) - {bad_id})
    for strict in (False, True):
        nav = NaVILA(fail_query=instructions[bad_id])
        out = tmp_path / ("strict" if strict else "lenient")
        with SequentialServer(nav) as server:
            agent = f"socket:127.0.0.1:{server.port}?server=navila&retries=1&timeout=30"
            proc, records, summary = run_eval(sage3d, dataset, out, agent, extra=("--strict",) if strict else ())
        if strict:
            assert proc.returncode != 0, f"expected a non-zero exit with --strict and one failed episode, got 0:\n{proc.stdout}"
        else:
            assert proc.returncode == 0, (
                f"expected exit 0 without --strict when only one episode failed, got {proc.returncode}:\n{proc.stderr}"
            )
        assert server.violations == [] and nav.violations == [], (
            f"expected no protocol violations, got {server.violations + nav.violations}"
        )
        assert summary["failed"] == [bad_id], f"expected only {bad_id} failed (strict={strict}), got {summary['failed']}"
        assert summary["failures"] == {"model_server": 1}, f"expected failures {{'model_server': 1}}, got {summary['failures']}"
        assert summary["faults"] == {"server_error": 2}, f"expected faults {{'server_error': 2}}, got {summary['faults']}"
        assert records[bad_id].get("failure") == "model_server", (
            f"expected {bad_id} to fail as model_server, got {records[bad_id].get('failure')!r}"
        )
        for eid in good:
            assert_scored(records[eid], NAVILA_ACTIONS)
            assert "faults" not in records[eid], f"{eid}: expected no faults, got {records[eid].get('faults')}"


def test_python_reads_agent_strings_as_the_cli_does():
    """The Python package canonicalises agent strings as the run record stores them, and knows
    that a NaVid server's episodes run one at a time (sage3d.distributed then runs its tasks
    one after another)."""
    from sage3d import _sage3d

    assert _sage3d.agent_spec("socket:h:9?server=NaVid&history=1") == {"name": "socket:h:9?server=navid", "serial": True}
    assert _sage3d.agent_spec("socket:h:9?server=navila&history=8") == {"name": "socket:h:9?server=navila", "serial": False}
    assert _sage3d.agent_spec("oracle") == {"name": "oracle", "serial": False}
    with pytest.raises(ValueError, match="navila, navid, mllm"):
        _sage3d.agent_spec("socket:h:9?server=habitat")
