"""Remote agents: ``muble serve`` (``muble.remote.server``) runs episodes that an agent in another process
drives over a versioned JSON protocol on ZeroMQ (``muble.remote.wire``, docs/remote.md);
``RemoteClient`` and ``run_agent`` are its Python side."""
from muble.remote.client import RemoteClient, RemoteError, RemoteStep, run_agent
from muble.remote.wire import PROTOCOL

__all__ = ["PROTOCOL", "RemoteClient", "RemoteError", "RemoteStep", "run_agent"]
