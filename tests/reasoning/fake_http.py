"""Test helper: a scripted fake HTTP server on 127.0.0.1 speaking enough of the Gemini and OpenAI REST formats."""

from __future__ import annotations

import base64
import io
import json
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest
from PIL import Image


@dataclass
class Reply:
    status: int = 200
    body: bytes = b"{}"
    delay_s: float = 0.0
    content_type: str = "application/json"


@dataclass
class FakeServer:
    replies: list[Reply] = field(default_factory=list)
    requests: list[tuple[str, dict, bytes]] = field(default_factory=list)
    url: str = ""

    def script(self, *replies: Reply) -> None:
        self.replies[:] = list(replies)


def png_b64(rgb: np.ndarray) -> str:
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode()


def json_reply(data: dict, status: int = 200, delay_s: float = 0.0) -> Reply:
    return Reply(status, json.dumps(data).encode(), delay_s)


def gemini_image(rgb: np.ndarray) -> Reply:
    parts = [{"text": "Here is the edited image."}, {"inlineData": {"mimeType": "image/png", "data": png_b64(rgb)}}]
    return json_reply({"candidates": [{"content": {"role": "model", "parts": parts}, "finishReason": "STOP"}]})


def gemini_text(text: str) -> Reply:
    parts = [{"text": text}]
    return json_reply({"candidates": [{"content": {"role": "model", "parts": parts}, "finishReason": "STOP"}]})


def gemini_error(code: int) -> Reply:
    status = {429: "RESOURCE_EXHAUSTED", 500: "INTERNAL", 503: "UNAVAILABLE"}.get(code, "INVALID_ARGUMENT")
    return json_reply({"error": {"code": code, "message": f"fake {code}", "status": status}}, status=code)


def openai_image(rgb: np.ndarray) -> Reply:
    return json_reply({"created": 1, "data": [{"b64_json": png_b64(rgb)}]})


def openai_chat(content: str | None, refusal: str | None = None) -> Reply:
    message = {"role": "assistant", "content": content, "refusal": refusal}
    choice = {"index": 0, "message": message, "finish_reason": "stop", "logprobs": None}
    return json_reply({"id": "c1", "object": "chat.completion", "created": 1, "model": "fake", "choices": [choice]})


def openai_error(code: int) -> Reply:
    return json_reply({"error": {"message": f"fake {code}", "type": "error", "code": None}}, status=code)


@pytest.fixture
def fake_server():
    server = FakeServer()

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:
            pass

        def do_POST(self) -> None:
            body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
            server.requests.append((self.path, {k.lower(): v for k, v in self.headers.items()}, body))
            reply = server.replies.pop(0) if server.replies else Reply(500, b'{"error": "unscripted"}')
            if reply.delay_s:
                time.sleep(reply.delay_s)
            try:
                self.send_response(reply.status)
                self.send_header("Content-Type", reply.content_type)
                self.send_header("Content-Length", str(len(reply.body)))
                self.end_headers()
                self.wfile.write(reply.body)
            except (BrokenPipeError, ConnectionResetError):
                pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    httpd.daemon_threads = True
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    server.url = f"http://127.0.0.1:{httpd.server_address[1]}"
    yield server
    httpd.shutdown()
    httpd.server_close()


@pytest.fixture
def scene_rgb() -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
