"""``muble serve`` against hostile and unlucky clients, on 127.0.0.1, with real servers and real sockets.

- the 59-byte request that used to end the server (a ``hello`` whose ``id`` is a lone surrogate);
- 1,000 structured fuzz messages (unicode edge cases, huge integers, deep nesting, wrong types, oversized
  documents, mutations of valid requests), each answered with a precise error code, after which the server
  serves on;
- 20 clients that vanish mid-reset, whose sessions are reclaimed at once; then a clean episode succeeds;
- ``hello`` answered within 1 s during another session's long reset (rendering on: the reset holds the
  simulation for seconds);
- no server-side path in a reply; option values checked (exit 2, one line, no traceback).

Every socket has a receive time-out and every loop a fixed count, so the suite is bounded in count and time.
"""
from __future__ import annotations

import json
import os
import random
import socket
import subprocess
import sys
import time

import pytest

from muble import get_registry
from muble.remote import PROTOCOL, RemoteClient, run_agent
from muble.remote.wire import ERROR_CODES, MAX_DEPTH

from tests.remote.server import REPO, ServerProcess

MAX_REQUEST = 65536
MAX_OBJECTS = 64
RECEIVE_MS = 60_000
FUZZ_MESSAGES = 1000
VANISHING_CLIENTS = 20
HELLO_LIMIT_S = 1.0

OBJECT = {"file": "mug1", "name": "mug", "shape": "cylindrical", "size": "small", "material": "ceramic",
          "colour": "red", "3d_coords": [0.55, -0.1, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0], "weight_gt": 250.0,
          "stackable": False, "stack_base": False, "pickupable": True}
INSTRUCTION = {"instruction": "How heavy is the mug?", "program": [{"type": "scene"}],
               "template_id": "measure_weight_single", "task_id": "measure_weight"}


def request(kind: str, **fields) -> dict:
    return {"protocol": PROTOCOL, "type": kind, **fields}


def text(document: dict) -> bytes:
    return json.dumps(document).encode()


class Dealer:
    """A DEALER socket speaking raw frames (with REQ's empty delimiter), so any frames can be sent."""

    def __init__(self, context, endpoint: str, timeout_ms: int = RECEIVE_MS):
        import zmq

        self.socket = context.socket(zmq.DEALER)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.RCVTIMEO, timeout_ms)
        self.socket.connect(endpoint)

    def ask(self, frames: list[bytes]) -> tuple[dict, list[bytes]]:
        self.socket.send_multipart([b"", *frames])
        reply = self.socket.recv_multipart()
        assert reply[0] == b"", "the reply lost its delimiter frame"
        return json.loads(reply[1].decode("ascii")), reply[2:]  # replies are ASCII JSON

    def close(self) -> None:
        self.socket.close(0)


@pytest.fixture(scope="module")
def zmq_context():
    import zmq

    context = zmq.Context()
    yield context
    context.term()


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A dataset root with one stored episode whose scene breaks the bounds (a position of 1e308 m)."""
    root = tmp_path_factory.mktemp("served_dataset")
    for folder in ("scenes", "instructions"):
        (root / "val" / folder).mkdir(parents=True)
    far = {"objects": [{**OBJECT, "3d_coords": [1e308, 0.0, 0.0]}]}
    (root / "val" / "scenes" / "SHOP_VRB2_val_000000.json").write_text(json.dumps(far))
    (root / "val" / "instructions" / "SHOP_VRB2_val_000000.json").write_text(json.dumps(INSTRUCTION))
    return root


@pytest.fixture(scope="module")
def server(dataset):
    """No rendering, one session at a time, small requests, sessions idle for long before they expire."""
    process = ServerProcess("--no-render", "--max-sessions", "1", "--max-request-bytes", str(MAX_REQUEST),
                            "--session-timeout", "600", f"dataset.root={dataset}", idle_exit=300)
    try:
        yield process
    finally:
        process.stop()


# ------------------------------------------------------------------------------------------ the one message
def test_a_lone_surrogate_in_the_id_is_answered_and_the_server_lives(server, zmq_context):
    raw = b'{"protocol": "muble.remote/1", "type": "hello", "id": "\\ud800"}'
    assert len(raw) < 64
    client = Dealer(zmq_context, server.endpoint)
    try:
        answer, _ = client.ask([raw])
        assert answer["type"] == "error" and answer["error"]["code"] == "bad_request", answer
        assert "surrogate" in answer["error"]["message"] and answer["id"] is None
        answer, _ = client.ask([text(request("hello", id="after"))])
        assert answer["type"] == "hello" and answer["id"] == "after"
    finally:
        client.close()
    assert server.process.poll() is None


def test_precise_codes_and_no_server_path(server, zmq_context, dataset):
    cases = [
        (b'{"protocol": "muble.remote/1", "type": "hello", "id": ' + b"9" * 5000 + b"}", "bad_request"),
        (text(request("hello", id=2**70)), "bad_request"),
        (text(request("reset", episode={"split": "val", "index": 7})), "not_found"),
        (text(request("reset", episode={"split": "test", "index": 0})), "not_found"),
        (text(request("reset", episode={"scene_index": 0, "template": "no_such_template"})), "not_found"),
        (text(request("reset", episode={"split": "val", "index": 0}, images="none")), "episode_error"),
        (text(request("reset", episode={"scene": {"objects": [OBJECT] * (MAX_OBJECTS + 1)},
                                        "instruction": INSTRUCTION})), "too_large"),
        (text(request("reset", episode={"scene": {"objects": [{**OBJECT, "3d_coords": [0, 0, 1e300]}]},
                                        "instruction": INSTRUCTION})), "episode_error"),
        (text(request("hello", id="x", nest=json.loads("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1)))),
         "too_large"),
        (b'{"protocol": "muble.remote/1", "type": "hello", "x": NaN}', "bad_request"),
        (b'{"protocol": "muble.remote/1", "type": "hello", "x": 1e400}', "bad_request"),
    ]
    client = Dealer(zmq_context, server.endpoint)
    try:
        for raw, code in cases:
            answer, _ = client.ask([raw])
            assert answer["type"] == "error" and answer["error"]["code"] == code, (raw[:100], answer)
            message = answer["error"]["message"]
            assert str(dataset) not in message and str(REPO) not in message and "/tmp/" not in message, message
            if b'"split": "val", "index": 0' in raw:  # the stored scene at fault is named, not where it is
                assert "SHOP_VRB2_val_000000.json" in message and "3d_coords" in message, message
    finally:
        client.close()


# ------------------------------------------------------------------------------------------------ the fuzz
UNICODE_EDGES = ["\ud800", "\udfff", "a\udc00b", "\ud83d\ude00", "\u0000", "\ufeff", "\u202e", "\uffff",
                 "\U0010ffff", "e\u0301", "\u2028", "x" * 10_000, "", " ", "..", "../../etc/passwd", "NUL\x00"]
HUGE_NUMBERS = [2**63, -(2**63) - 1, 10**19, 10**4000, 2**63 - 1, -0.0, 1e308, 1e-320, 5e-324]
RAW_NUMBERS = [b"1e400", b"-1e400", b"NaN", b"Infinity", b"-Infinity", b"9" * 4400, b"-" + b"9" * 5000, b"1" * 300]


def nested(rng: random.Random, depth: int):
    value = rng.choice([[], {}, 0, "x"])
    for _ in range(depth):
        value = [value] if rng.random() < 0.5 else {"k": value}
    return value


def any_value(rng: random.Random, depth: int = 0):
    kind = rng.randrange(9)
    if kind == 0:
        return rng.choice(UNICODE_EDGES)
    if kind == 1:
        return rng.choice(HUGE_NUMBERS)
    if kind == 2:
        return nested(rng, rng.choice([3, MAX_DEPTH - 3, MAX_DEPTH, MAX_DEPTH + 5, 200]))
    if kind == 3:
        return rng.choice([None, True, False, 0, -1, 1.5, "", [], {}])
    if kind == 4 and depth < 3:
        return [any_value(rng, depth + 1) for _ in range(rng.randrange(4))]
    if kind == 5 and depth < 3:
        return {rng.choice(UNICODE_EDGES[:6] + ["id", "type", "a"]): any_value(rng, depth + 1)
                for _ in range(rng.randrange(4))}
    if kind == 6:
        return "y" * rng.choice([10, MAX_REQUEST // 2, MAX_REQUEST + 1])
    return rng.randrange(-5, 100)


def valid_requests(holder: str, rng: random.Random) -> list[dict]:
    """Requests of every type, valid in shape; a mutation makes most of them invalid."""
    data = {"scene": {"objects": [dict(OBJECT) for _ in range(rng.randrange(1, 4))]}, "instruction": dict(INSTRUCTION)}
    return [
        request("hello", id=rng.randrange(100)),
        request("reset", episode={"scene_index": rng.randrange(50), "template": "measure_weight_single"},
                images=rng.choice(["png", "raw", "none"])),
        request("reset", episode={"scene_index": rng.randrange(50)}),
        request("reset", episode={"split": "val", "index": rng.randrange(3)}),
        request("reset", episode=data, images="none"),
        request("observe", session=holder),
        request("act", session=holder, action={"name": 7, "params": {"target": 1}}),  # malformed: never runs
        request("act", session=secrets_like(rng), action={"stop": True}),
        request("close", session=secrets_like(rng)),
    ]


def secrets_like(rng: random.Random) -> str:
    return "".join(rng.choice("0123456789abcdef") for _ in range(32))


def mutate(document, rng: random.Random):
    """One structural change somewhere in the document: a value replaced, a key removed or added."""
    if not isinstance(document, (dict, list)) or not document:
        return any_value(rng)
    container, path = document, []
    while isinstance(container, (dict, list)) and container and rng.random() < 0.6:
        key = rng.choice(list(container)) if isinstance(container, dict) else rng.randrange(len(container))
        if not isinstance(container[key], (dict, list)) or not container[key]:
            break
        path.append(key)
        container = container[key]
    key = rng.choice(list(container)) if isinstance(container, dict) else rng.randrange(len(container))
    action = rng.randrange(3)
    if action == 0:
        container[key] = any_value(rng)
    elif action == 1 and isinstance(container, dict):
        del container[key]
    elif isinstance(container, dict):
        container[rng.choice(UNICODE_EDGES[:8] + ["extra", "session", "episode"])] = any_value(rng)
    else:
        container.append(any_value(rng))
    return document


def fuzz_messages(holder: str, rng: random.Random) -> list[list[bytes]]:
    """``FUZZ_MESSAGES`` messages, each a list of frames."""
    messages: list[list[bytes]] = []
    while len(messages) < FUZZ_MESSAGES:
        kind = rng.randrange(10)
        base = rng.choice(valid_requests(holder, rng))
        if kind <= 4:  # a valid request, mutated one to three times
            document = base
            for _ in range(rng.randrange(1, 4)):
                document = mutate(document, rng)
            messages.append([json.dumps(document, ensure_ascii=rng.random() < 0.5).encode("utf-8", "surrogatepass")])
        elif kind == 5:  # a raw number JSON cannot or Python should not hold, in a random field
            raw = rng.choice(RAW_NUMBERS)
            field = rng.choice([b"id", b"scene_index", b"index", b"x"])
            messages.append([b'{"protocol": "muble.remote/1", "type": "reset", "episode": {"' + field + b'": '
                             + raw + b"}, \"id\": " + raw + b"}"])
        elif kind == 6:  # deep nesting, as text (past what Python's parser takes, too)
            depth = rng.choice([MAX_DEPTH, MAX_DEPTH + 1, 1000, 50_000])
            messages.append([b'{"protocol": "muble.remote/1", "type": "hello", "x": ' + b"[" * depth + b"]" * depth
                             + b"}"])
        elif kind == 7:  # random bytes, invalid UTF-8 included, or JSON cut short
            if rng.random() < 0.5:
                messages.append([bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))])
            else:
                whole = text(base)
                messages.append([whole[:rng.randrange(1, len(whole))]])
        elif kind == 8:  # several frames, or an empty one
            messages.append([text(base)] * rng.randrange(2, 4) if rng.random() < 0.8 else [b""])
        else:  # oversized: past the byte limit, or many objects within it
            if rng.random() < 0.5:
                messages.append([text({**base, "pad": "z" * (MAX_REQUEST + rng.randrange(1, 1000))})])
            else:
                objects = [OBJECT] * rng.randrange(MAX_OBJECTS + 1, 200)
                many = {"scene": {"objects": objects}, "instruction": INSTRUCTION}
                messages.append([text(request("reset", episode=many, images="none"))])
    return messages


def test_a_thousand_fuzz_messages_get_precise_errors_and_the_server_serves_on(server, zmq_context):
    rng = random.Random(34)
    with RemoteClient(server.endpoint, timeout=300) as holder:
        # The one session slot is taken, so a fuzzed reset that happens to be valid is answered busy at once.
        holder.reset({"scene_index": 0, "template": "measure_weight_single"}, images="none")
        messages = fuzz_messages(holder.session, rng)
        assert len(messages) == FUZZ_MESSAGES
        client = Dealer(zmq_context, server.endpoint)
        codes: dict[str, int] = {}
        kinds: dict[str, int] = {}
        start = time.monotonic()
        try:
            for frames in messages:
                answer, _ = client.ask(frames)
                kinds[answer["type"]] = kinds.get(answer["type"], 0) + 1
                if answer["type"] == "error":
                    code = answer["error"]["code"]
                    codes[code] = codes.get(code, 0) + 1
                    assert code in ERROR_CODES and code != "internal", (frames[0][:200], answer)
                    assert "Traceback" not in answer["error"]["message"]
                else:
                    assert answer["type"] in ("hello", "observation"), answer
        finally:
            client.close()
        seconds = time.monotonic() - start
        print(f"fuzz: {FUZZ_MESSAGES} messages in {seconds:.1f} s; replies {kinds}; error codes {codes}")
        assert server.process.poll() is None, "the server stopped"
        assert {"bad_request", "too_large", "unsupported_protocol", "busy", "unknown_session"} <= set(codes), codes
        assert holder.hello()["open_sessions"] == 1
        observed = holder.observe().header  # the holder's episode is untouched
        assert observed["session"] == holder.session and observed["observation"]["last_result"] is None
        objects = observed["observation"]["scene"]["objects"]
        assert [o["id"] for o in objects] == list(range(len(objects)))  # every object names its id


# --------------------------------------------------------------------------------------- vanishing clients
@pytest.fixture(scope="module")
def soak_server():
    """Two sessions at a time, idle sessions kept for 600 s: a slot freed sooner was freed because its client
    was seen to have gone."""
    process = ServerProcess("--no-render", "--session-timeout", "600", idle_exit=300)
    try:
        yield process
    finally:
        process.stop()


def test_clients_that_vanish_mid_reset_leave_no_session_behind(soak_server, zmq_context):
    rng = random.Random(20)
    started = time.monotonic()
    for k in range(VANISHING_CLIENTS):
        client = Dealer(zmq_context, soak_server.endpoint)
        client.socket.send_multipart([b"", text(request("reset", episode={
            "scene_index": k, "template": "measure_weight_single"}, images="none"))])
        time.sleep(rng.uniform(0.05, 0.3))  # long enough for the request to leave, far shorter than a reset
        client.close()
    with RemoteClient(soak_server.endpoint, timeout=120) as client:
        # Resets may still be running for clients that are gone (a warm simulation process may already have
        # finished them all, its replies undeliverable): either way no session may be left.
        deadline = time.monotonic() + 180
        while client.hello()["open_sessions"] and time.monotonic() < deadline:
            time.sleep(0.5)
        assert client.hello()["open_sessions"] == 0, "sessions of vanished clients were kept"
        print(f"vanished clients' sessions reclaimed {time.monotonic() - started:.1f} s after the first reset")
        record = run_agent(get_registry().create("agent", "oracle", {}), client,
                           {"scene_index": 0, "template": "measure_weight_single"})
    assert record["outcome"] == "success", record
    assert soak_server.process.poll() is None


def simulation_pid(server: ServerProcess) -> int:
    """The simulation process among the server's children (the other is multiprocessing's resource tracker)."""
    pid = server.process.pid
    children = open(f"/proc/{pid}/task/{pid}/children").read().split()
    found = [int(c) for c in children if b"spawn_main" in open(f"/proc/{c}/cmdline", "rb").read()]
    assert len(found) == 1, children
    return found[0]


def test_a_crashed_simulation_costs_its_episodes_not_the_server(soak_server, zmq_context):
    """A native crash (here: SIGKILL) of the simulation process mid-reset: the reset is answered with an error,
    a fresh simulation process starts, and the next episode runs."""
    import signal

    client = Dealer(zmq_context, soak_server.endpoint, timeout_ms=300_000)
    try:
        for delay in (1.0, 0.3, 0.05, 0.0):  # a warm simulation process may finish a reset before the kill
            client.socket.send_multipart([b"", text(request("reset", id="doomed", episode={
                "scene_index": 1, "template": "measure_weight_single"}, images="none"))])
            time.sleep(delay)
            if client.socket.poll(0):  # answered already: close that session and kill sooner
                finished = json.loads(client.socket.recv_multipart()[1])
                client.ask([text(request("close", session=finished["session"]))])
                continue
            os.kill(simulation_pid(soak_server), signal.SIGKILL)
            break
        else:
            pytest.fail("every reset finished before the simulation process could be killed")
        reply = client.socket.recv_multipart()
        answer = json.loads(reply[1])
        assert answer["type"] == "error" and answer["id"] == "doomed", answer
        assert answer["error"]["code"] == "episode_error" and "simulation" in answer["error"]["message"]
        answer, _ = client.ask([text(request("hello"))])
        assert answer["type"] == "hello" and answer["open_sessions"] == 0
        answer, _ = client.ask([text(request("reset", episode={"scene_index": 0, "template": "measure_weight_single"},
                                             images="none"))])
        assert answer["type"] == "observation" and not answer["done"], answer
        answer, _ = client.ask([text(request("close", session=answer["session"]))])
        assert answer["type"] == "closed"
    finally:
        client.close()
    assert soak_server.process.poll() is None


# ------------------------------------------------------------------------------------- hello during a reset
@pytest.mark.gl
def test_hello_answers_within_a_second_during_a_long_reset(zmq_context):
    """With rendering on, a reset builds a MuJoCo world and an OpenGL context and draws the first frame: seconds
    of work that holds Python's interpreter lock for a second and more at a time. The server's request loop
    runs apart from it; a session whose client leaves after its reply is reclaimed after --session-timeout."""
    process = ServerProcess("--session-timeout", "5", idle_exit=300)
    try:
        worker = Dealer(zmq_context, process.endpoint, timeout_ms=300_000)
        asker = Dealer(zmq_context, process.endpoint)
        asker.ask([text(request("hello"))])
        worker.socket.send_multipart([b"", text(request("reset", episode={
            "scene_index": 0, "template": "stack_simple"}, images="png"))])
        latencies = []
        while not worker.socket.poll(0):
            start = time.monotonic()
            answer, _ = asker.ask([text(request("hello"))])
            latencies.append(time.monotonic() - start)
            assert answer["type"] == "hello"
            time.sleep(0.05)
        reply = worker.socket.recv_multipart()
        header = json.loads(reply[1])
        assert header["type"] == "observation" and header["images"], header.get("error")
        assert len(latencies) >= 10, "the reset was too short to measure anything"
        print(f"hello during a reset: {len(latencies)} answered, longest {max(latencies) * 1000:.0f} ms")
        assert max(latencies) < HELLO_LIMIT_S
        worker.close()  # leaves without closing its session
        deadline = time.monotonic() + 60
        while asker.ask([text(request("hello"))])[0]["open_sessions"] and time.monotonic() < deadline:
            time.sleep(0.5)
        assert asker.ask([text(request("hello"))])[0]["open_sessions"] == 0
        asker.close()
    finally:
        process.stop()


# --------------------------------------------------------------------------------------------- the options
def _port_in_use():
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    return listener


@pytest.mark.parametrize("args, says", [
    (["--max-sessions", "0"], "--max-sessions"),
    (["--max-request-bytes", "-1"], "--max-request-bytes"),
    (["--session-timeout", "nan"], "--session-timeout"),
    (["--idle-exit", "-5"], "--idle-exit"),
    (["--host", "999.1.1.1"], "--host"),
    (["--max-objects", "100000"], "--max-objects"),
    (["--port", "PORT_IN_USE"], "in use"),
    (["renderer.widht=3"], "renderer.width"),
])
def test_bad_option_values_exit_2_with_one_line(args, says):
    listener = _port_in_use()
    try:
        args = [str(listener.getsockname()[1]) if a == "PORT_IN_USE" else a for a in args]
        env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
        result = subprocess.run([sys.executable, "-m", "muble.app.cli", "serve", "--no-render", *args], cwd=REPO,
                                env=env, capture_output=True, text=True, timeout=120)
    finally:
        listener.close()
    message = result.stderr.strip()
    assert result.returncode == 2, message[-2000:]
    assert "Traceback" not in message and len(message.splitlines()) == 1 and says in message, message
    assert "listening" not in result.stdout


# -------------------------------------------------------------------------------------- the hello contract
def test_hello_carries_json_schemas_of_primitive_parameters(server):
    jsonschema = pytest.importorskip("jsonschema")
    with RemoteClient(server.endpoint, timeout=60) as client:
        hello = client.hello()
    assert hello["max_objects"] == MAX_OBJECTS and hello["session_timeout"] == 600 and hello["stored_episodes"]
    primitives = {p["name"]: p for p in hello["primitives"]}
    for entry in primitives.values():
        jsonschema.Draft202012Validator.check_schema(entry["parameters"])
    valid = jsonschema.Draft202012Validator(primitives["approach"]["parameters"])
    assert valid.is_valid({"target": 3}) and valid.is_valid({"target": 3, "attempt": 1})
    assert not valid.is_valid({"target": "left"}) and not valid.is_valid({}) and not valid.is_valid(
        {"target": 3, "speed": 1})
    move = jsonschema.Draft202012Validator(primitives["move"]["parameters"])
    assert move.is_valid({"target": "left"}) and move.is_valid({"target": 2}) and not move.is_valid({"target": "up"})
    lift = jsonschema.Draft202012Validator(primitives["lift"]["parameters"])
    assert lift.is_valid({"height": 0.2}) and not lift.is_valid({"height": 1.0})
