"""A minimal LSP client for tests and benchmarks: spawns `python -m acl lsp` and speaks JSON-RPC
over its stdio with Content-Length framing."""
from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def serve(stdin: bytes, timeout: float = 60) -> tuple[int, list[dict], str, bytes]:
    """Run `acl lsp` on the raw bytes ``stdin``: (exit code, the messages it wrote, its stderr, its raw stdout)."""
    import re

    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.run([sys.executable, "-m", "acl", "lsp"], input=stdin, capture_output=True, timeout=timeout,
                       env=env, cwd=ROOT)
    out, msgs = p.stdout, []
    while out:
        head, _, rest = out.partition(b"\r\n\r\n")
        m = re.search(rb"Content-Length: (\d+)", head)
        if m is None:
            break
        n = int(m.group(1))
        msgs.append(json.loads(rest[:n]))
        out = rest[n:]
    return p.returncode, msgs, p.stderr.decode("utf-8", "replace"), p.stdout


def uri(path) -> str:
    return Path(path).resolve().as_uri()


class LspClient:
    def __init__(self, init_options: dict | None = None, cwd=None, capabilities: dict | None = None,
                 root: Path | None = None):
        env = dict(os.environ)
        env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
        self.proc = subprocess.Popen([sys.executable, "-m", "acl", "lsp"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=cwd or ROOT)
        self._id = 0
        self.responses: dict[int, dict] = {}
        self.notifications: "queue.Queue[dict]" = queue.Queue()
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.stderr_lines: list[str] = []
        threading.Thread(target=self._drain_stderr, daemon=True).start()
        self.init_result = self.request("initialize", {"processId": os.getpid(), "rootUri": uri(root or ROOT),
                                                       "capabilities": capabilities or {},
                                                       "initializationOptions": init_options or {}})
        self.notify("initialized", {})

    # ------------------------------------------------------------------------------ transport
    def _send(self, msg: dict) -> None:
        body = json.dumps(msg).encode("utf-8")
        self.proc.stdin.write(f"Content-Length: {len(body)}\r\n\r\n".encode("ascii") + body)
        self.proc.stdin.flush()

    def _read(self) -> None:
        out = self.proc.stdout
        while True:
            headers = {}
            while True:
                line = out.readline()
                if not line:
                    return
                line = line.decode("ascii").strip()
                if not line:
                    break
                k, v = line.split(":", 1)
                headers[k.strip().lower()] = v.strip()
            body = out.read(int(headers["content-length"]))
            msg = json.loads(body)
            if "id" in msg and "method" not in msg:
                with self._cond:
                    self.responses[msg["id"]] = msg
                    self._cond.notify_all()
            elif "id" in msg:          # a request from the server (e.g. workspace/configuration)
                self._send({"jsonrpc": "2.0", "id": msg["id"], "result": None})
            else:
                msg["_t"] = time.perf_counter()
                self.notifications.put(msg)

    def _drain_stderr(self) -> None:
        for line in self.proc.stderr:
            self.stderr_lines.append(line.decode("utf-8", "replace"))

    def request(self, method: str, params: dict, timeout: float = 60.0):
        self._id += 1
        rid = self._id
        self._send({"jsonrpc": "2.0", "id": rid, "method": method, "params": params})
        deadline = time.monotonic() + timeout
        with self._cond:
            while rid not in self.responses:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"no answer to {method} in {timeout} s; stderr: {''.join(self.stderr_lines)[-2000:]}")
                self._cond.wait(left)
            msg = self.responses.pop(rid)
        if "error" in msg:
            raise RuntimeError(f"{method}: {msg['error']}")
        return msg.get("result")

    def notify(self, method: str, params: dict) -> None:
        self._send({"jsonrpc": "2.0", "method": method, "params": params})

    def wait_for(self, method: str, predicate=lambda p: True, timeout: float = 60.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {method} in {timeout} s; stderr: {''.join(self.stderr_lines)[-2000:]}")
            try:
                msg = self.notifications.get(timeout=left)
            except queue.Empty:
                continue
            if msg.get("method") == method and predicate(msg["params"]):
                msg["params"]["_t"] = msg["_t"]
                return msg["params"]

    # ------------------------------------------------------------------------------ documents
    def open(self, path, text: str | None = None, version: int = 1) -> str:
        u = uri(path)
        text = Path(path).read_text(encoding="utf-8") if text is None else text
        self.notify("textDocument/didOpen", {"textDocument": {"uri": u, "languageId": "acl", "version": version,
                                                              "text": text}})
        return u

    def change(self, u: str, version: int, text: str) -> None:
        self.notify("textDocument/didChange", {"textDocument": {"uri": u, "version": version},
                                               "contentChanges": [{"text": text}]})

    def edit(self, u: str, version: int, line: int, start: int, end: int, new: str) -> None:
        self.notify("textDocument/didChange", {"textDocument": {"uri": u, "version": version}, "contentChanges": [
            {"range": {"start": {"line": line, "character": start}, "end": {"line": line, "character": end}},
             "text": new}]})

    def at(self, method: str, u: str, line: int, character: int, **extra):
        return self.request(method, {"textDocument": {"uri": u}, "position": {"line": line, "character": character},
                                     **extra})

    def close(self) -> None:
        try:
            self.request("shutdown", None, timeout=10)
            self.notify("exit", None)
            self.proc.wait(timeout=10)
        except Exception:
            self.proc.kill()
            self.proc.wait(timeout=10)
        finally:
            for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
                try:
                    f.close()
                except Exception:
                    pass
