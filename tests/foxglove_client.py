"""Test helpers for Foxglove output: decode messages with the schemas they carry (protobuf
file descriptor sets of Foxglove's official schemas, or JSON Schema), and a minimal WebSocket
client of the Foxglove WebSocket protocol (RFC 6455 framing; the standard library only)."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time
from typing import Any

import jsonschema
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.json_format import MessageToDict

SUBPROTOCOL = "foxglove.sdk.v1"


class Decoder:
    """Message bytes -> dict, with the schema each channel declares (cached per schema)."""

    def __init__(self):
        self._cache: dict[tuple[str, bytes], Any] = {}

    def decode(self, name: str, encoding: str, schema: bytes, data: bytes) -> dict:
        key = (name, schema)
        if encoding == "protobuf":
            cls = self._cache.get(key)
            if cls is None:
                pool = descriptor_pool.DescriptorPool()
                for fd in descriptor_pb2.FileDescriptorSet.FromString(schema).file:
                    pool.Add(fd)
                cls = self._cache[key] = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
            msg = cls.FromString(data)
            return MessageToDict(msg, preserving_proto_field_name=True)
        if encoding == "jsonschema":
            validator = self._cache.get(key)
            if validator is None:
                doc_schema = json.loads(schema)
                cls = jsonschema.validators.validator_for(doc_schema)
                cls.check_schema(doc_schema)  # a valid JSON Schema, checked once
                validator = self._cache[key] = cls(doc_schema)
            doc = json.loads(data)
            validator.validate(doc)  # raises on a message the schema refuses
            return doc
        raise AssertionError(f"unexpected schema encoding {encoding!r}")


class FoxgloveClient:
    """Connects to ``ws://127.0.0.1:PORT``, reads the advertisements, subscribes to every
    channel and collects decoded messages: ``messages[topic] -> [(log_time ns, dict)]``."""

    def __init__(self, port: int, timeout: float = 30.0, subprotocol: str = SUBPROTOCOL):
        deadline = time.monotonic() + timeout
        while True:  # the server may still be starting
            try:
                self.sock = socket.create_connection(("127.0.0.1", port), timeout=5)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                           f"Sec-WebSocket-Version: 13\r\n"
                           f"Sec-WebSocket-Protocol: {subprotocol}\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            head += chunk
        assert head.startswith(b"HTTP/1.1 101"), head
        self.channels: dict[int, dict] = {}
        self.subs: dict[int, int] = {}  # subscription id -> channel id
        self.server_info: dict | None = None
        self.messages: dict[str, list[tuple[int, dict]]] = {}
        self.decoder = Decoder()

    def _read_exact(self, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("server closed the connection")
            buf += chunk
        return buf

    def _frame(self) -> tuple[int, bytes]:
        b0, b1 = self._read_exact(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._read_exact(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._read_exact(8))[0]
        mask = self._read_exact(4) if b1 & 0x80 else None
        data = self._read_exact(n)
        if mask:
            data = bytes(c ^ mask[i % 4] for i, c in enumerate(data))
        return b0 & 0x0F, data

    def send_json(self, obj: dict) -> None:
        data = json.dumps(obj).encode()
        mask = os.urandom(4)
        n = len(data)
        head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n)
                                if n < 65536 else bytes([0x80 | 127]) + struct.pack(">Q", n))
        self.sock.sendall(head + mask + bytes(c ^ mask[i % 4] for i, c in enumerate(data)))

    def pump(self, seconds: float, until=None) -> None:
        """Read for up to ``seconds``, subscribing to each new channel, until ``until(self)``."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline and not (until and until(self)):
            self.sock.settimeout(max(0.05, deadline - time.monotonic()))
            try:
                op, data = self._frame()
            except TimeoutError:
                break
            if op == 0x1:
                msg = json.loads(data)
                if msg["op"] == "serverInfo":
                    self.server_info = msg
                elif msg["op"] == "advertise":
                    new = []
                    for ch in msg["channels"]:
                        self.channels[ch["id"]] = ch
                        sid = len(self.subs) + 1
                        self.subs[sid] = ch["id"]
                        new.append({"id": sid, "channelId": ch["id"]})
                    self.send_json({"op": "subscribe", "subscriptions": new})
            elif op == 0x2 and data[0] == 0x01:  # MessageData
                sid, log_time = struct.unpack("<IQ", data[1:13])
                ch = self.channels[self.subs[sid]]
                schema = ch["schema"]
                raw = base64.b64decode(schema) if ch.get("schemaEncoding") == "protobuf" else schema.encode()
                decoded = self.decoder.decode(ch["schemaName"], ch.get("schemaEncoding", ""), raw, data[13:])
                self.messages.setdefault(ch["topic"], []).append((log_time, decoded))
            elif op == 0x8:
                break

    def close(self) -> None:
        self.sock.close()
