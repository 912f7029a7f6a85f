"""``muble serve`` answers every request — malformed, oversized, out of order — and keeps serving; it listens on
loopback only unless told otherwise."""
from __future__ import annotations

import json
import random

import pytest

from muble.app.config import SHOPVRB2_TEMPLATES
from muble.remote import PROTOCOL, RemoteClient, RemoteError

from tests.remote.server import ServerProcess

MAX_REQUEST = 65536


@pytest.fixture(scope="module")
def server():
    process = ServerProcess("--no-render", "--max-request-bytes", str(MAX_REQUEST), idle_exit=120)
    try:
        yield process
    finally:
        process.stop()


def header(kind, **fields):
    return json.dumps({"protocol": PROTOCOL, "type": kind, **fields}).encode()


def malformed_requests(rng: random.Random) -> list[list[bytes]]:
    """Two hundred and more requests no server should take, of every kind the protocol rejects."""
    fixed = [
        [b""], [b"\xff\xfe\x00"], [b"not json"], [b"[1, 2]"], [b"null"], [b"42"], [b'"text"'],
        [b"{" * 5000], [b"[" * 100000], [b'{"type": "hello"}'], [b'{"protocol": "muble.remote/9", "type": "hello"}'],
        [b'{"protocol": 1, "type": "hello"}'], [header("dance")], [header("hello", id={"a": 1})],
        [header("hello", id="x" * 100)], [header("hello"), b"extra frame"], [header("hello"), b"", b""],
        [b"x" * (MAX_REQUEST + 1)], [header("reset", episode={"scene_index": 0}, pad="y" * MAX_REQUEST)],
        [header("act")], [header("act", session=None)], [header("act", session="0" * 32, action={"stop": True})],
        [header("observe", session=12)], [header("close", session="nope")],
        [header("reset")], [header("reset", episode=[])], [header("reset", episode={"scene_index": -1})],
        [header("reset", episode={"scene_index": True})], [header("reset", episode={"scene_index": 2**40})],
        [header("reset", episode={"scene_index": 0, "template": "fly_away"})],
        [header("reset", episode={"scene_index": 0, "template": 5})],
        [header("reset", episode={"split": "../../etc", "index": 0})],
        [header("reset", episode={"split": "val", "index": "0"})],
        [header("reset", episode={"scene": {"objects": "many"}, "instruction": {}})],
        [header("reset", episode={"scene": [], "instruction": []})],
        [header("reset", episode={"scene_index": 0}, images="jpeg")], [header("reset", unknown=1)],
        [header("hello", extra=True)],
    ]
    random_ones = []
    for _ in range(200):
        kind = rng.randrange(4)
        if kind == 0:  # random bytes
            random_ones.append([bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))])
        elif kind == 1:  # a valid header with a random request type or field
            random_ones.append([header(rng.choice(["act", "observe", "close", "reset", "x", ""]),
                                       session=rng.choice([None, "", "a" * rng.randrange(64), 7]),
                                       **{rng.choice(["action", "episode", "images", "zz"]): rng.choice(
                                           [None, 1, "s", [], {}, {"name": 1}, {"stop": "yes"}])})])
        elif kind == 2:  # JSON cut short
            text = header("act", session="s", action={"name": "move", "params": {"target": 1}})
            random_ones.append([text[:rng.randrange(1, len(text))]])
        else:  # several frames
            random_ones.append([header("hello")] * rng.randrange(2, 5))
    return fixed + random_ones


def test_nothing_listens_beyond_loopback_by_default(server):
    addresses = server.listening_addresses()
    assert addresses, "the server listens on no TCP socket"
    assert all(address == "127.0.0.1" for address, _ in addresses), addresses
    assert server.endpoint.startswith("tcp://127.0.0.1:")


def test_malformed_messages_get_error_replies_and_the_server_keeps_serving(server):
    import zmq

    requests = malformed_requests(random.Random(0))
    assert len(requests) >= 200
    context = zmq.Context()
    socket = context.socket(zmq.DEALER)  # raw frames: no REQ envelope rules on what we may send
    socket.setsockopt(zmq.LINGER, 0)
    socket.setsockopt(zmq.RCVTIMEO, 60000)
    socket.connect(server.endpoint)
    codes = {}
    try:
        for frames in requests:
            socket.send_multipart([b"", *frames])
            reply = socket.recv_multipart()
            assert reply[0] == b""
            answer = json.loads(reply[1])
            assert answer["type"] == "error", (frames[0][:80], answer)
            codes[answer["error"]["code"]] = codes.get(answer["error"]["code"], 0) + 1
    finally:
        socket.close(0)
        context.term()
    assert server.process.poll() is None, "the server stopped"
    assert {"bad_request", "unsupported_protocol", "too_large", "unknown_session"} <= set(codes), codes
    with RemoteClient(server.endpoint, timeout=120) as client:
        hello = client.hello()
        assert hello["protocol"] == PROTOCOL and set(SHOPVRB2_TEMPLATES) <= set(hello["templates"])
        assert "stack_stiffness_order" in hello["templates"]  # every registered task may be asked for
        with pytest.raises(RemoteError) as e:
            client.request("act", session="f" * 32, action={"stop": True})
        assert e.value.code == "unknown_session"


def test_an_episode_is_one_session_and_out_of_order_requests_are_refused(server):
    with RemoteClient(server.endpoint, timeout=300) as client:
        step = client.reset({"scene_index": 0, "template": "measure_weight_single"}, images="none")
        assert not step.done and "weight_gt" not in json.dumps(step.header["observation"]["scene"])
        token = client.session
        with pytest.raises(RemoteError) as e:
            client.act({"name": 3})  # not a call's shape: refused, the episode goes on
        assert e.value.code == "bad_request"
        step = client.act({"name": "fly", "params": {}})  # a call no primitive accepts: the agent's fault
        assert step.done and step.outcome == "invalid_action"
        with pytest.raises(RemoteError) as e:
            client.act({"stop": True})
        assert e.value.code == "out_of_order"
        client.close_session()
        with pytest.raises(RemoteError) as e:
            client.request("observe", session=token)
        assert e.value.code == "unknown_session"
