"""A loopback Hub-protocol server (stdlib only) for tests and the offline demo.

Implements the endpoints huggingface_hub 1.x uses for `create_repo`, `upload_folder` (preupload with
`uploadMode: "regular"`, NDJSON commit), tags, refs, `repo_info`, tree listing, `whoami` and file
download (`resolve`, with the ETag / X-Repo-Commit / Content-Length headers `hf_hub_download` needs).
Repositories live in memory. It binds 127.0.0.1 only and stops when its `with` block ends (or on
`stop()`); `lifetime_s` optionally stops it earlier as a safety net for long-lived demo processes.
Not a general Hub: no LFS/Xet, no pull requests, no pagination.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Self
from urllib.parse import parse_qs, unquote, urlsplit

logger = logging.getLogger(__name__)

MAX_BODY_BYTES = 512 * 1024 * 1024  # largest accepted request body
MAX_REPOS = 256


def git_blob_oid(data: bytes) -> str:
    """The git blob sha1 the Hub reports as a regular file's `oid`."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


@dataclass
class _Repo:
    repo_id: str
    repo_type: str
    commits: dict[str, dict[str, bytes]] = field(default_factory=dict)  # sha -> {path: content}
    branches: dict[str, str] = field(default_factory=dict)  # name -> sha
    tags: dict[str, str] = field(default_factory=dict)  # name -> sha

    def commit(self, files: dict[str, bytes], branch: str = "main") -> str:
        sha = hashlib.sha1(f"{self.repo_id}:{len(self.commits)}:{time.time_ns()}".encode()).hexdigest()
        self.commits[sha] = files
        self.branches[branch] = sha
        return sha

    def resolve(self, revision: str) -> str | None:
        revision = revision.removeprefix("refs/heads/").removeprefix("refs/tags/")
        if revision in self.branches:
            return self.branches[revision]
        if revision in self.tags:
            return self.tags[revision]
        return revision if revision in self.commits else None


class _Handler(BaseHTTPRequestHandler):
    server: LoopbackHub._Server  # type: ignore[name-defined]

    def log_message(self, format: str, *args) -> None:
        logger.debug("loopback hub: " + format, *args)

    # ----------------------------------------------------------------------------- replies
    def _send(self, status: int, body: bytes = b"", headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, obj, error_code: str | None = None) -> None:
        headers = {"Content-Type": "application/json"}
        if error_code:
            headers.update(
                {
                    "X-Error-Code": error_code,
                    "X-Error-Message": str(obj.get("error", "")),
                }
            )
        self._send(status, json.dumps(obj).encode(), headers)

    def _body(self) -> bytes:
        length = int(self.headers.get("Content-Length") or 0)
        if length > MAX_BODY_BYTES:
            raise ValueError(f"request body of {length} bytes exceeds {MAX_BODY_BYTES}")
        return self.rfile.read(length)

    # ----------------------------------------------------------------------------- dispatch
    def do_HEAD(self) -> None:
        self._dispatch()

    def do_GET(self) -> None:
        self._dispatch()

    def do_POST(self) -> None:
        self._dispatch()

    def do_DELETE(self) -> None:
        self._dispatch()

    def _dispatch(self) -> None:
        hub = self.server.hub
        token = hub.token
        if token is not None and self.headers.get("Authorization") != f"Bearer {token}":
            self._json(401, {"error": "Invalid credentials in Authorization header"})
            return
        url = urlsplit(self.path)
        parts = url.path.strip("/").split("/")  # still percent-encoded: revisions may contain '/'
        query = parse_qs(url.query)
        try:
            with hub.lock:
                self._route(hub, parts, query)
        except (ValueError, KeyError, json.JSONDecodeError) as err:
            self._json(400, {"error": f"bad request: {err}"})

    def _route(self, hub: LoopbackHub, parts: list[str], query: dict) -> None:
        m = self.command
        if parts[:2] == ["api", "whoami-v2"]:
            return self._json(
                200,
                {
                    "type": "user",
                    "name": hub.user,
                    "fullname": hub.user,
                    "orgs": [],
                    "auth": {"type": "access_token", "accessToken": {"role": "write"}},
                },
            )
        if parts[:2] == ["api", "validate-yaml"] and m == "POST":  # README front matter check
            self._body()
            return self._json(200, {"errors": [], "warnings": []})
        if parts[:3] == ["api", "repos", "create"] and m == "POST":
            payload = json.loads(self._body())
            repo_type = payload.get("type") or "model"
            repo_id = f"{payload.get('organization') or hub.user}/{payload['name']}"
            url = f"{hub.url}/{'' if repo_type == 'model' else repo_type + 's/'}{repo_id}"
            if (repo_type, repo_id) in hub.repos:
                return self._json(409, {"error": "You already created this repo", "url": url})
            if len(hub.repos) >= MAX_REPOS:
                return self._json(507, {"error": f"loopback hub holds at most {MAX_REPOS} repos"})
            repo = hub.repos[(repo_type, repo_id)] = _Repo(repo_id, repo_type)
            repo.commit({".gitattributes": b"*.safetensors filter=lfs diff=lfs merge=lfs -text\n"})
            return self._json(200, {"url": url, "name": repo_id})
        if parts[0] == "api" and len(parts) >= 4 and parts[1] in ("models", "datasets", "spaces"):
            repo_type, repo_id = (
                parts[1][:-1],
                f"{unquote(parts[2])}/{unquote(parts[3])}",
            )
            repo = hub.repos.get((repo_type, repo_id))
            if repo is None:
                return self._json(404, {"error": f"Repository {repo_id} not found"}, "RepoNotFound")
            return self._api(repo, parts[4:], query)
        if m in ("GET", "HEAD") and len(parts) >= 5:
            repo_type = "model"
            if parts[0] in ("datasets", "spaces"):
                repo_type, parts = parts[0][:-1], parts[1:]
            if len(parts) >= 5 and parts[2] == "resolve":
                repo = hub.repos.get((repo_type, f"{unquote(parts[0])}/{unquote(parts[1])}"))
                if repo is None:
                    return self._json(404, {"error": "Repository not found"}, "RepoNotFound")
                return self._resolve(repo, unquote(parts[3]), unquote("/".join(parts[4:])))
        return self._json(404, {"error": f"loopback hub has no route for {m} {self.path}"})

    # ----------------------------------------------------------------------------- repo API
    def _api(self, repo: _Repo, rest: list[str], query: dict) -> None:
        m = self.command
        if not rest or rest[0] == "revision":
            revision = unquote(rest[1]) if len(rest) > 1 else "main"
            sha = repo.resolve(revision)
            if sha is None:
                return self._json(404, {"error": f"Invalid rev id: {revision}"}, "RevisionNotFound")
            files = repo.commits[sha]
            return self._json(
                200,
                {
                    "id": repo.repo_id,
                    "sha": sha,
                    "private": False,
                    "tags": [],
                    "siblings": [{"rfilename": p, "size": len(files[p])} for p in sorted(files)],
                },
            )
        if rest[0] == "refs":

            def ref(kind: str, name: str, sha: str) -> dict:
                return {"name": name, "ref": f"refs/{kind}/{name}", "targetCommit": sha}

            return self._json(
                200,
                {
                    "branches": [ref("heads", n, s) for n, s in repo.branches.items()],
                    "tags": [ref("tags", n, s) for n, s in repo.tags.items()],
                    "converts": [],
                    "pullRequests": [],
                },
            )
        if rest[0] == "tag" and len(rest) == 2:
            if m == "DELETE":
                if repo.tags.pop(unquote(rest[1]), None) is None:
                    return self._json(404, {"error": f"tag {rest[1]} not found"}, "RevisionNotFound")
                return self._json(200, {})
            tag = json.loads(self._body())["tag"]
            sha = repo.resolve(unquote(rest[1]))
            if sha is None:
                return self._json(404, {"error": f"Invalid rev id: {rest[1]}"}, "RevisionNotFound")
            if tag in repo.tags:
                return self._json(409, {"error": f"tag {tag} already exists"})
            repo.tags[tag] = sha
            return self._json(200, {})
        if rest[0] in ("preupload", "commit", "tree") and len(rest) >= 2:
            revision = unquote(rest[1])
            sha = repo.resolve(revision)
            if sha is None and not (rest[0] == "commit" and revision == "main"):
                return self._json(404, {"error": f"Invalid rev id: {revision}"}, "RevisionNotFound")
            files = repo.commits.get(sha, {})
            if rest[0] == "preupload":
                wanted = json.loads(self._body())["files"]
                return self._json(
                    200,
                    {
                        "files": [
                            {
                                "path": f["path"],
                                "uploadMode": "regular",
                                "shouldIgnore": False,
                                "oid": git_blob_oid(files[f["path"]]) if f["path"] in files else None,
                            }
                            for f in wanted
                        ]
                    },
                )
            if rest[0] == "commit":
                return self._commit(repo, revision, dict(files))
            return self._tree(
                files,
                unquote("/".join(rest[2:])),
                query.get("recursive", ["false"])[0].lower() == "true",
            )
        return self._json(404, {"error": f"loopback hub has no route for {m} {self.path}"})

    def _commit(self, repo: _Repo, branch: str, files: dict[str, bytes]) -> None:
        for line in self._body().splitlines():
            if not line.strip():
                continue
            item = json.loads(line)
            key, value = item["key"], item["value"]
            if key == "file":
                files[value["path"]] = base64.b64decode(value["content"])
            elif key == "deletedFile":
                files.pop(value["path"], None)
            elif key == "deletedFolder":
                prefix = value["path"].rstrip("/") + "/"
                files = {p: c for p, c in files.items() if not p.startswith(prefix)}
            elif key != "header":
                return self._json(
                    400,
                    {"error": f"loopback hub supports only regular uploads, got {key!r}"},
                )
        sha = repo.commit(files, branch)
        prefix = "" if repo.repo_type == "model" else f"{repo.repo_type}s/"
        url = f"{self.server.hub.url}/{prefix}{repo.repo_id}/commit/{sha}"
        return self._json(
            200,
            {
                "commitUrl": url,
                "commitOid": sha,
                "success": True,
                "pullRequestUrl": None,
            },
        )

    def _tree(self, files: dict[str, bytes], root: str, recursive: bool) -> None:
        prefix = f"{root.strip('/')}/" if root.strip("/") else ""
        entries, folders = [], set()
        for path in sorted(p for p in files if p.startswith(prefix)):
            rel = path[len(prefix) :].split("/")
            for depth in range(1, len(rel) if recursive else min(len(rel), 2)):
                folders.add(prefix + "/".join(rel[:depth]))
            if recursive or len(rel) == 1:
                entries.append(
                    {
                        "type": "file",
                        "path": path,
                        "size": len(files[path]),
                        "oid": git_blob_oid(files[path]),
                    }
                )
        entries += [
            {
                "type": "directory",
                "path": d,
                "oid": hashlib.sha1(d.encode()).hexdigest(),
            }
            for d in sorted(folders)
        ]
        return self._json(200, entries)

    def _resolve(self, repo: _Repo, revision: str, path: str) -> None:
        sha = repo.resolve(revision)
        if sha is None:
            return self._json(404, {"error": f"Invalid rev id: {revision}"}, "RevisionNotFound")
        content = repo.commits[sha].get(path)
        if content is None:
            return self._json(404, {"error": f"{path} does not exist"}, "EntryNotFound")
        self._send(
            200,
            content,
            {
                "ETag": f'"{git_blob_oid(content)}"',
                "X-Repo-Commit": sha,
                "Content-Type": "application/octet-stream",
            },
        )


class LoopbackHub:
    """In-memory Hub on 127.0.0.1; `with LoopbackHub() as hub: ... HF_ENDPOINT=hub.url` (stops at the end)."""

    class _Server(ThreadingHTTPServer):
        daemon_threads = True
        hub: LoopbackHub

    def __init__(
        self,
        lifetime_s: float | None = None,
        token: str | None = None,
        user: str = "loopback",
    ) -> None:
        if lifetime_s is not None and lifetime_s <= 0:
            raise ValueError(f"lifetime_s must be > 0 (or None: until stop()), got {lifetime_s}")
        self.lifetime_s, self.token, self.user = lifetime_s, token, user
        self.repos: dict[tuple[str, str], _Repo] = {}
        self.lock = threading.Lock()
        self._server: LoopbackHub._Server | None = None

    @property
    def url(self) -> str:
        if self._server is None:
            raise RuntimeError("LoopbackHub is not running: call start() or use it as a context manager")
        host, port = self._server.server_address[:2]
        return f"http://{host}:{port}"

    def start(self) -> Self:
        self._server = self._Server(("127.0.0.1", 0), _Handler)
        self._server.hub = self
        threading.Thread(
            target=self._server.serve_forever,
            kwargs={"poll_interval": 0.1},
            daemon=True,
        ).start()
        if self.lifetime_s is not None:
            threading.Thread(target=self._watchdog, daemon=True).start()
        logger.info("loopback hub listening on %s", self.url)
        return self

    def _watchdog(self) -> None:
        started = time.monotonic()
        while self._server is not None and time.monotonic() - started < self.lifetime_s:
            time.sleep(0.2)
        self.stop()

    def stop(self) -> None:
        server, self._server = self._server, None
        if server is not None:
            server.shutdown()
            server.server_close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
