"""The Python client of ``muble serve``: open an episode, observe, act, answer; and ``run_agent`` to drive one
with any in-process ``Agent`` (the oracle, a baseline, a reasoner) from this process.

    from muble.remote import RemoteClient, run_agent
    with RemoteClient("tcp://127.0.0.1:5555") as client:
        step = client.reset({"scene_index": 0, "template": "stack_simple"})
        while not step.done:
            step = client.act({"name": "move", "params": {"target": 1}})   # … your agent's calls
"""
from __future__ import annotations

import io
import json
import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from muble.core.errors import MubleError
from muble.core.interfaces import Agent, Instruction, reset_agent
from muble.core.types import Frame, Observation, ObservationMode, Outcome, Track
from muble.episode.plain import decision_to_plain, observation_from_plain
from muble.io.instructions_io import instruction_from_dict
from muble.remote.wire import DEFAULT_HOST, DEFAULT_PORT, PROTOCOL

if TYPE_CHECKING:  # pragma: no cover
    import zmq

log = logging.getLogger(__name__)


class RemoteError(MubleError):
    """An error reply of the server (``code`` as in ``muble.remote.wire.ERROR_CODES``) or no reply in time."""

    def __init__(self, code: str, message: str):
        super().__init__(f"{code}: {message}")
        self.code = code


@dataclass
class RemoteStep:
    """One observation reply: the header, the images decoded, and the episode's end when ``done``."""

    header: dict[str, Any]
    images: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        return bool(self.header.get("done"))

    @property
    def outcome(self) -> str | None:
        return self.header.get("outcome")

    def observation(self) -> Observation:
        """The ``Observation`` an in-process agent would get at this step."""
        frames = {c: Frame(camera=c, rgb=rgb) for c, rgb in self.images.items()}
        return observation_from_plain(self.header["observation"], frames)


def decode_images(header: dict[str, Any], frames: list[bytes]) -> dict[str, np.ndarray]:
    images = {}
    for entry in header.get("images", []):
        data = frames[entry["frame"]]
        if entry["format"] == "png":
            from PIL import Image

            images[entry["camera"]] = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
        else:
            images[entry["camera"]] = np.frombuffer(data, dtype=np.uint8).reshape(entry["shape"])
    return images


class RemoteClient:
    """A connection to ``muble serve`` holding at most one open session (episode) at a time."""

    def __init__(self, address: str = f"tcp://{DEFAULT_HOST}:{DEFAULT_PORT}", timeout: float = 900.0):
        import zmq

        self.address = address
        self.timeout_ms = int(timeout * 1000)
        self.context = zmq.Context()
        self.socket: zmq.Socket[bytes] = self._new_socket()
        self.session: str | None = None
        self._next_id = 0

    def _new_socket(self) -> zmq.Socket[bytes]:
        import zmq

        socket = self.context.socket(zmq.REQ)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        socket.connect(self.address)
        return socket

    def _connect(self) -> None:
        self.socket.close(0)
        self.socket = self._new_socket()

    def request(self, kind: str, **fields: Any) -> tuple[dict[str, Any], list[bytes]]:
        """Send one request; returns the reply header and its frames, or raises ``RemoteError``."""
        import zmq

        self._next_id += 1
        header = {"protocol": PROTOCOL, "type": kind, "id": self._next_id, **fields}
        self.socket.send(json.dumps(header, allow_nan=False).encode("utf-8"))
        try:
            frames = self.socket.recv_multipart()
        except zmq.Again:
            self._connect()  # a REQ socket that missed its reply cannot send again
            raise RemoteError("timeout", f"no reply from {self.address} within {self.timeout_ms / 1000:.0f} s") from None
        reply = json.loads(frames[0])
        if reply.get("type") == "error":
            raise RemoteError(reply["error"]["code"], reply["error"]["message"])
        return reply, frames

    # ----------------------------------------------------------------------------------------------- episode
    def hello(self) -> dict[str, Any]:
        return self.request("hello")[0]

    def reset(self, episode: dict[str, Any], images: str = "png") -> RemoteStep:
        """Open a session on ``episode`` ({scene_index, template}, {split, index} or {scene, instruction}); the
        previous session, if any, is closed first."""
        if self.session is not None:
            self.close_session()
        header, frames = self.request("reset", episode=episode, images=images)
        self.session = header["session"]
        return RemoteStep(header, decode_images(header, frames))

    def observe(self) -> RemoteStep:
        header, frames = self.request("observe", session=self.session)
        return RemoteStep(header, decode_images(header, frames))

    def act(self, action: dict[str, Any]) -> RemoteStep:
        """``{"name", "params"}``, ``{"answer"[, "stop"]}`` or ``{"stop": true}``."""
        header, frames = self.request("act", session=self.session, action=action)
        return RemoteStep(header, decode_images(header, frames))

    def close_session(self) -> None:
        if self.session is not None:
            try:
                self.request("close", session=self.session)
            except RemoteError as e:
                log.info("closing session: %s", e)
            self.session = None

    def close(self) -> None:
        self.close_session()
        self.socket.close(0)
        self.context.term()

    def __enter__(self) -> "RemoteClient":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def run_agent(agent: Agent, client: RemoteClient, episode: dict[str, Any], images: str = "none") -> dict[str, Any]:
    """Run one episode on the server with ``agent`` deciding in this process; returns the episode's record
    (``outcome``, ``primitives``, ``answer``, ``error``, ``instruction``, ``template``) as ``muble eval`` has them.

    An agent that raises ends its episode here (``agent_error``, as in-process); the server's session is closed.
    """
    step = client.reset(episode, images=images)
    instruction: Instruction = instruction_from_dict(step.header["instruction"])
    record = {"episode": episode, "template": instruction.template_id, "instruction": instruction.instruction}
    try:
        if not step.done:
            try:
                reset_agent(agent, instruction, step.observation(), track=Track(step.header["track"]),
                            mode=ObservationMode(step.header["mode"]))
            except Exception as e:  # noqa: BLE001 - the agent's fault ends its episode, as in-process
                return {**record, "outcome": Outcome.AGENT_ERROR.value, "primitives": [], "answer": None,
                        "error": f"agent.reset raised {type(e).__name__}: {e}"}
        while not step.done:
            try:
                decision = agent.act(instruction, step.observation())
            except Exception as e:  # noqa: BLE001 - see above
                return {**record, "outcome": Outcome.AGENT_ERROR.value, "primitives": [], "answer": None,
                        "error": f"agent.act raised {type(e).__name__}: {e}"}
            step = client.act(decision_to_plain(decision))
        h = step.header
        return {**record, "outcome": h["outcome"], "error": h.get("error"), "answer": h.get("answer"),
                "primitives": [_call_text(a) for a in h.get("actions", [])]}
    finally:
        client.close_session()


def _call_text(action: dict[str, Any]) -> str:
    args = ", ".join(f"{k}={v!r}" for k, v in action.get("params", {}).items())
    return f"{action['name']}({args})"
