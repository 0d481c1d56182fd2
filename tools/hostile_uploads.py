#!/usr/bin/env python3
"""Hostile-upload sweep of a running silva service.

Posts malformed point clouds of every supported format (XYZ, PLY ascii and
binary, LAS, LAZ) and hostile transport variants (wrong Content-Type,
Content-Encoding, lying Content-Length, chunked floods, hostile metadata) to
every route of the service that takes a request body, follows any job an
upload queues to its end, and reports per case: HTTP status, content type,
problem title and detail, job outcome and time.

The project standard (docs/api-fuzzing.md): bad input gets a typed 4xx
problem+json answer, or is accepted (202) and its job fails with a clear
error. Flagged:

- any 5xx answer, or an error answer that is not application/problem+json;
- any request or job that takes longer than --timeout (a hang);
- a job error that reads as a fault of the service (panic, internal error);
- a panic or internal-error line in the server log (--server-log);
- the server unhealthy after the sweep, or the baseline tree (uploaded first)
  damaged by the hostile rescans that target it.

The script starts nothing itself. LAS and LAZ cases are made by corrupting a
valid file that `silva synth --scan als` writes (the binary is an argument).
Standard library and numpy only.

Usage:

    cd "$(mktemp -d)" && silva serve --listen 127.0.0.1:18080 2> server.log &
    python3 tools/hostile_uploads.py --base-url http://127.0.0.1:18080 \\
        --silva target/release/silva --server-log server.log

Exit status 0 when nothing was flagged, 1 otherwise. `--json FILE` also
writes every case's result as JSON; `--only SUBSTRING` runs matching cases.
"""

from __future__ import annotations

import argparse
import gzip
import http.client
import json
import os
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.parse
from dataclasses import dataclass, field

import numpy as np

PROBLEM_JSON = "application/problem+json"
# Words in a job error that name a fault of the service, not of the upload.
INTERNAL_WORDS = ("panicked", "panic", "internal", "the service failed", "lease was lost")

# LAS 1.4 header field offsets (ASPRS LAS 1.4 R15, Table 3).
LAS_VERSION_MINOR = 25
LAS_HEADER_SIZE = 94
LAS_OFFSET_TO_POINTS = 96
LAS_NUMBER_OF_VLRS = 100
LAS_POINT_FORMAT = 104
LAS_RECORD_LEN = 105
LAS_LEGACY_COUNT = 107
LAS_SCALE = 131
LAS_OFFSET = 155
LAS_EVLR_START = 235
LAS_COUNT = 247


@dataclass
class Case:
    """One hostile request."""

    name: str
    body: bytes | None
    headers: dict[str, str] = field(default_factory=dict)
    query: str = ""
    # "plain": one request with Content-Length; "chunked": body streamed in
    # chunks of `chunk` bytes, `repeat` times; "lying-length": a
    # Content-Length larger than the body, then the connection is closed.
    transport: str = "plain"
    chunk: bytes = b""
    repeat: int = 0
    # Rescans of the baseline tree: its stored model must survive.
    targets_baseline: bool = False


@dataclass
class Result:
    """What the service answered to one case on one route."""

    case: str
    route: str
    status: int | None = None
    content_type: str = ""
    title: str = ""
    detail: str = ""
    job: str = ""
    job_error: str = ""
    seconds: float = 0.0
    flags: list[str] = field(default_factory=list)


# ---------------------------------------------------------------- HTTP


class Client:
    """A tiny HTTP/1.1 client over http.client (one connection per request,
    so a server that closes early never poisons the next case)."""

    def __init__(self, base_url: str, api_key: str | None, timeout: float):
        url = urllib.parse.urlsplit(base_url)
        self.host = url.hostname or "127.0.0.1"
        self.port = url.port or 80
        self.timeout = timeout
        self.auth = {"Authorization": f"Bearer {api_key}"} if api_key else {}

    def connection(self) -> http.client.HTTPConnection:
        return http.client.HTTPConnection(self.host, self.port, timeout=self.timeout)

    def request(self, method: str, path: str, body: bytes | None = None,
                headers: dict[str, str] | None = None) -> tuple[int, dict[str, str], bytes]:
        conn = self.connection()
        try:
            conn.request(method, path, body=body, headers={**self.auth, **(headers or {})})
            res = conn.getresponse()
            return res.status, {k.lower(): v for k, v in res.getheaders()}, res.read()
        finally:
            conn.close()

    def get_json(self, path: str):
        status, _, body = self.request("GET", path)
        return status, (json.loads(body) if body else None)

    def streamed(self, path: str, headers: dict[str, str],
                 write) -> tuple[int, dict[str, str], bytes]:
        """POSTs with `headers` and lets `write(conn)` send the body; the
        server may answer and close before taking it all."""
        conn = self.connection()
        try:
            conn.putrequest("POST", path)
            for k, v in {**self.auth, **headers}.items():
                conn.putheader(k, v)
            conn.endheaders()
            try:
                write(conn)
            except OSError:  # the server answered and closed first
                pass
            res = conn.getresponse()
            return res.status, {k.lower(): v for k, v in res.getheaders()}, res.read()
        finally:
            conn.close()

    def chunked(self, path: str, chunk: bytes, repeat: int,
                headers: dict[str, str]) -> tuple[int, dict[str, str], bytes]:
        """Streams `repeat` chunks without a Content-Length (a 413 is due
        once they pass the server's body limit)."""
        frame = f"{len(chunk):x}\r\n".encode() + chunk + b"\r\n"

        def write(conn: http.client.HTTPConnection) -> None:
            for _ in range(repeat):
                conn.send(frame)
            conn.send(b"0\r\n\r\n")

        return self.streamed(path, {**headers, "Transfer-Encoding": "chunked"}, write)

    def lying_length(self, path: str, body: bytes, claimed: int,
                     headers: dict[str, str]) -> tuple[int, dict[str, str], bytes]:
        """Declares `claimed` bytes, sends `body` (shorter) and half-closes:
        the server must answer (413 when over the limit, 400 for a body cut
        short) rather than wait forever."""
        def write(conn: http.client.HTTPConnection) -> None:
            conn.send(body)
            conn.sock.shutdown(socket.SHUT_WR)  # no more bytes will come

        return self.streamed(path, {**headers, "Content-Length": str(claimed)}, write)


# ---------------------------------------------------------------- files


def xyz(points: np.ndarray) -> bytes:
    return "".join(f"{x:.4f} {y:.4f} {z:.4f}\n" for x, y, z in points).encode()


def ply_ascii(points: np.ndarray, count: int | None = None) -> bytes:
    n = len(points) if count is None else count
    head = f"ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    return head.encode() + xyz(points)


def ply_binary(points: np.ndarray, count: int | None = None, endian: str = "<",
               scalar: str = "double") -> bytes:
    n = len(points) if count is None else count
    name = {"<": "binary_little_endian", ">": "binary_big_endian"}[endian]
    code = {"double": "d", "float": "f"}[scalar]
    head = (f"ply\nformat {name} 1.0\nelement vertex {n}\n"
            f"property {scalar} x\nproperty {scalar} y\nproperty {scalar} z\nend_header\n")
    return head.encode() + points.astype(endian + code).tobytes()


def patch(data: bytes, offset: int, fmt: str, value) -> bytes:
    """`data` with one little-endian field overwritten."""
    out = bytearray(data)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


def flip_bytes(data: bytes, start: int, count: int, seed: int) -> bytes:
    """`count` random bytes after `start` replaced by random values."""
    rng = np.random.default_rng(seed)
    out = bytearray(data)
    for i in rng.integers(start, len(data), size=count):
        out[i] = int(rng.integers(0, 256))
    return bytes(out)


def synth_files(silva: str, workdir: str) -> dict[str, bytes]:
    """A valid LAS and LAZ of one synthetic oak (airborne scan), and its
    true skeleton as JSON, LsJSON and chain code."""
    def path(name: str) -> str:
        return os.path.join(workdir, name)

    for ext in ("las", "laz"):
        subprocess.run([silva, "synth", "--scan", "als", "--seed", "3", "-o", path(f"tree.{ext}"),
                        "--truth", path("skeleton.json")], check=True, stdout=subprocess.DEVNULL)
    subprocess.run([silva, "encode", path("skeleton.json"), "--lsystem", path("tree.lsjson"),
                    "--chaincode", path("tree.chain")], check=True, stdout=subprocess.DEVNULL)
    out = {}
    for name in ("tree.las", "tree.laz", "skeleton.json", "tree.lsjson", "tree.chain"):
        with open(path(name), "rb") as f:
            out[name] = f.read()
    return out


def count64(data: bytes, count: int) -> bytes:
    """`data` claiming `count` points in the LAS 1.4 64-bit field, with the
    legacy 32-bit field zeroed so that readers use the 64-bit one."""
    return patch(patch(data, LAS_COUNT, "<Q", count), LAS_LEGACY_COUNT, "<I", 0)


def las_points_start(las: bytes) -> int:
    return struct.unpack_from("<I", las, LAS_OFFSET_TO_POINTS)[0]


# ---------------------------------------------------------------- cases


def tree_points(rng: np.random.Generator, n: int = 3000) -> np.ndarray:
    """A crude tree: a vertical trunk and a ball of crown points (readable,
    possibly reconstructable; only the hostile variations matter)."""
    z = rng.uniform(0, 8, n // 3)
    a = rng.uniform(0, 2 * np.pi, n // 3)
    trunk = np.column_stack([0.2 * np.cos(a), 0.2 * np.sin(a), z])
    crown = rng.normal([0, 0, 10], 2.0, (n - n // 3, 3))
    return np.vstack([trunk, crown]) + [155000.0, 463000.0, 0.0]


def xyz_cases(rng: np.random.Generator) -> list[Case]:
    pts = tree_points(rng)
    good = xyz(pts)
    lines = good.splitlines(keepends=True)
    n = 20000
    return [
        Case("xyz/empty", b""),
        Case("xyz/whitespace-only", b"   \n\t\n\r\n"),
        Case("xyz/comments-only", b"# x y z\n// header\n"),
        Case("xyz/one-point", b"1 2 3\n"),
        Case("xyz/four-points", b"0 0 0\n0 0 1\n0 0 2\n1 1 1\n"),
        Case("xyz/nan", b"0 0 0\n1 nan 2\n"),
        Case("xyz/inf", b"0 0 0\ninf 1 2\n"),
        Case("xyz/overflow-1e999", b"0 0 0\n1e999 1 2\n"),
        Case("xyz/junk-text", b"hello world, this is not a cloud\n"),
        Case("xyz/junk-line-in-middle", b"".join(lines[:500]) + b"x y z\n" + b"".join(lines[500:])),
        Case("xyz/two-columns", b"1 2\n3 4\n"),
        Case("xyz/commas-only", b",,,\n,,,\n"),
        Case("xyz/hex-floats", b"0x10 0x20 0x30\n"),
        Case("xyz/endless-line", b"1 " * 100_000),
        Case("xyz/nul-bytes", b"0 0 0\n1 1\x00 1\n"),
        Case("xyz/invalid-utf8-mid", b"0 0 0\n" * 2000 + b"1 1 \xff\xfe\n"),
        Case("xyz/bom", b"\xef\xbb\xbf" + good),
        Case("xyz/implausible-1e12", b"1e12 0 0\n"),
        Case("xyz/span-over-100km", b"0 0 0\n200000 0 0\n"),
        Case("xyz/near-limit-1e8", xyz(pts - pts.mean(0) + 9.9e8)),
        Case("xyz/micrometre-ball-20k", xyz(rng.normal(0, 1e-6, (n, 3)))),
        Case("xyz/crlf-tree", good.replace(b"\n", b"\r\n")),
        Case("xyz/many-columns", b"1 2 3 " + b"4 " * 1500 + b"\n"),
        Case("xyz/random-binary", rng.bytes(4096)),
    ]


def geometry_cases(rng: np.random.Generator) -> list[Case]:
    """Readable clouds no tree can come from, in every reconstruction mode:
    accepted (202), and the job must fail with a clear reason, in time."""
    pts = tree_points(rng)
    n = 20000
    shapes = {
        "identical": np.tile([155000.0, 463000.0, 5.0], (n, 1)),
        "collinear-vertical": np.column_stack([np.zeros(n), np.zeros(n), np.linspace(0, 10, n)]),
        "collinear-horizontal": np.column_stack([np.linspace(0, 10, n), np.zeros(n), np.zeros(n)]),
        "coplanar-ground": np.column_stack([rng.uniform(0, 10, n), rng.uniform(0, 10, n), np.zeros(n)]),
        "coplanar-wall": np.column_stack([rng.uniform(0, 10, n), np.zeros(n), rng.uniform(0, 10, n)]),
        "ten-points": pts[:10],
        "tree-plus-outlier-99km-up": np.vstack([pts, pts[0] + [0, 0, 99_000]]),
        "tree-plus-outlier-99km-east": np.vstack([pts, pts[0] + [99_000, 0, 0]]),
        "two-trees-99km-apart": np.vstack([pts, pts + [99_000, 99_000, 0]]),
        "tree-upside-down": pts * [1, 1, -1],
        "uniform-noise-cube": rng.uniform(0, 30, (n, 3)),
    }
    return [Case(f"geom/{name}/{mode}", xyz(points), query=f"mode={mode}")
            for name, points in shapes.items() for mode in ("auto", "dense", "airborne")]


def ply_cases(rng: np.random.Generator) -> list[Case]:
    pts = tree_points(rng, 600)
    head = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    nan_pts = pts.copy()
    nan_pts[7, 1] = np.nan
    inf_pts = pts.copy()
    inf_pts[3, 2] = np.inf
    return [
        Case("ply/no-end-header", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"),
        Case("ply/magic-only", b"ply\n"),
        Case("ply/ascii-count-lies-high", ply_ascii(pts, count=len(pts) + 1000)),
        Case("ply/ascii-count-lies-low", ply_ascii(pts, count=10)),
        Case("ply/binary-count-lies-high", ply_binary(pts, count=len(pts) + 1000)),
        Case("ply/binary-count-4-billion", ply_binary(pts, count=4_000_000_000)),
        Case("ply/binary-count-2^64", ply_binary(pts, count=2 ** 64)),
        Case("ply/count-negative", ply_ascii(pts, count=-5)),
        Case("ply/count-zero", ply_ascii(pts[:0], count=0)),
        Case("ply/count-not-a-number", head.replace(b"vertex 3", b"vertex three") + b"0 0 0\n"),
        Case("ply/no-x-property", head.replace(b"property float x\n", b"") + b"0 0\n0 0\n0 0\n"),
        Case("ply/unknown-type", head.replace(b"float x", b"float128 x") + b"0 0 0\n" * 3),
        Case("ply/list-x", head.replace(b"property float x", b"property list uchar int x") + b"1 0 0 0\n" * 3),
        Case("ply/duplicate-x", head.replace(b"property float y", b"property float x") + b"0 0 0\n" * 3),
        Case("ply/unknown-format", head.replace(b"ascii 1.0", b"binary_middle_endian 1.0")),
        Case("ply/format-version-2", head.replace(b"ascii 1.0", b"ascii 2.0") + b"0 0 0\n" * 3),
        Case("ply/binary-le-nan", ply_binary(nan_pts)),
        Case("ply/binary-be-inf", ply_binary(inf_pts, endian=">")),
        Case("ply/binary-truncated-mid-record", ply_binary(pts)[:-5]),
        Case("ply/ascii-junk-row", ply_ascii(pts).replace(b"\n", b"\nnot numbers here\n", 20)),
        Case("ply/ascii-short-row", head + b"0 0 0\n1 1\n2 2 2\n"),
        Case("ply/huge-comment-header", b"ply\nformat ascii 1.0\n" + b"comment " + b"x" * 70_000 + b"\n"),
        Case("ply/many-comment-lines", b"ply\nformat ascii 1.0\n" + b"comment c\n" * 20_000 + head[20:]),
        Case("ply/face-before-vertex-lying",
             b"ply\nformat binary_little_endian 1.0\nelement face 4000000000\n"
             b"property list uchar int vertex_indices\nelement vertex 3\nproperty float x\n"
             b"property float y\nproperty float z\nend_header\n" + b"\x03" + b"\x00" * 12),
        Case("ply/uchar-coordinates", head.replace(b"float", b"uchar") + b"0 0 0\n1 1 1\n300 2 2\n"),
    ]


def las_cases(las: bytes, rng: np.random.Generator) -> list[Case]:
    start = las_points_start(las)
    rec = struct.unpack_from("<H", las, LAS_RECORD_LEN)[0]
    count = struct.unpack_from("<Q", las, LAS_COUNT)[0]
    return [
        Case("las/truncated-in-header", las[:100]),
        Case("las/truncated-before-points", las[:start]),
        Case("las/truncated-half-points", las[: start + rec * (count // 2) + 7]),
        Case("las/count-2^63", count64(las, 2 ** 63)),
        Case("las/count-plus-one", count64(las, count + 1)),
        Case("las/count-minus-one", count64(las, count - 1)),
        Case("las/legacy-count-max", patch(patch(las, LAS_COUNT, "<Q", 0), LAS_LEGACY_COUNT, "<I", 2 ** 32 - 1)),
        Case("las/offset-past-eof", patch(las, LAS_OFFSET_TO_POINTS, "<I", len(las) + 10)),
        Case("las/offset-zero", patch(las, LAS_OFFSET_TO_POINTS, "<I", 0)),
        Case("las/record-len-zero", patch(las, LAS_RECORD_LEN, "<H", 0)),
        Case("las/record-len-65535", patch(las, LAS_RECORD_LEN, "<H", 65535)),
        Case("las/header-size-zero", patch(las, LAS_HEADER_SIZE, "<H", 0)),
        Case("las/header-size-65535", patch(las, LAS_HEADER_SIZE, "<H", 65535)),
        Case("las/version-9.9", patch(patch(las, 24, "<B", 9), LAS_VERSION_MINOR, "<B", 9)),
        Case("las/vlr-count-huge", patch(las, LAS_NUMBER_OF_VLRS, "<I", 2 ** 32 - 1)),
        Case("las/point-format-99", patch(las, LAS_POINT_FORMAT, "<B", 99 & 0x3F)),
        Case("las/scale-zero", patch(las, LAS_SCALE, "<d", 0.0)),
        Case("las/scale-nan", patch(las, LAS_SCALE + 8, "<d", float("nan"))),
        Case("las/scale-1e300", patch(las, LAS_SCALE + 16, "<d", 1e300)),
        Case("las/scale-negative", patch(las, LAS_SCALE, "<d", -0.001)),
        Case("las/offset-inf", patch(las, LAS_OFFSET, "<d", float("inf"))),
        Case("las/evlr-past-eof", patch(las, LAS_EVLR_START, "<Q", len(las) + 1000)),
        Case("las/random-point-bytes", flip_bytes(las, start, 2000, 1)),
        Case("las/random-header-bytes", flip_bytes(las[:start], 4, 40, 2) + las[start:]),
        Case("las/magic-only", b"LASF"),
        Case("las/laz-bit-on-las", patch(las, LAS_POINT_FORMAT, "<B", las[LAS_POINT_FORMAT] | 0x80)),
    ]


def laz_cases(laz: bytes, rng: np.random.Generator) -> list[Case]:
    start = las_points_start(laz)
    count = struct.unpack_from("<Q", laz, LAS_COUNT)[0]
    body = len(laz) - start
    table = struct.unpack_from("<q", laz, start)[0]
    return [
        Case("laz/truncated-10%", laz[: start + body // 10]),
        Case("laz/truncated-50%", laz[: start + body // 2]),
        Case("laz/truncated-before-chunk-table", laz[:table] if 0 < table < len(laz) else laz[:-40]),
        Case("laz/truncated-last-byte", laz[:-1]),
        Case("laz/count-billions", count64(laz, 5_000_000_000)),
        Case("laz/count-2^64-1", count64(laz, 2 ** 64 - 1)),
        Case("laz/legacy-and-64-bit-counts-billions",
             patch(patch(laz, LAS_COUNT, "<Q", 5_000_000_000), LAS_LEGACY_COUNT, "<I", 2 ** 32 - 1)),
        Case("laz/legacy-count-4-billion", patch(patch(laz, LAS_COUNT, "<Q", 0), LAS_LEGACY_COUNT, "<I", 4_000_000_000)),
        Case("laz/count-plus-1000", count64(laz, count + 1000)),
        Case("laz/count-minus-1000", count64(laz, count - 1000)),
        Case("laz/count-below-max-points-lying", count64(laz, 19_000_000)),
        Case("laz/legacy-count-plus-1000", patch(laz, LAS_LEGACY_COUNT, "<I", count + 1000)),
        Case("laz/chunk-table-offset-garbage", patch(laz, start, "<q", 2 ** 62)),
        Case("laz/chunk-table-offset-negative", patch(laz, start, "<q", -1)),
        Case("laz/chunk-table-offset-zero", patch(laz, start, "<q", 0)),
        Case("laz/laszip-vlr-garbage", flip_bytes(laz[:start], 375 + 54, 30, 3) + laz[start:]),
        Case("laz/flip-compressed-1", flip_bytes(laz, start + 8, 50, 11)),
        Case("laz/flip-compressed-2", flip_bytes(laz, start + 8, 500, 12)),
        Case("laz/flip-compressed-3", flip_bytes(laz, start + 8, 5, 13)),
        Case("laz/zeroed-compressed", laz[: start + 8] + bytes(body - 8)),
        Case("laz/compression-bit-off", patch(laz, LAS_POINT_FORMAT, "<B", laz[LAS_POINT_FORMAT] & 0x3F)),
        Case("laz/record-len-mismatch", patch(laz, LAS_RECORD_LEN, "<H", 20)),
    ]


def transport_cases(las: bytes, laz: bytes, rng: np.random.Generator,
                    chunked_mib: int) -> list[Case]:
    good = xyz(tree_points(rng, 1500))
    bomb = gzip.compress(b"\x00" * (64 << 20), 9)
    boundary = "silvaXYZ"
    multipart = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"t.xyz\"\r\n"
                 f"Content-Type: text/plain\r\n\r\n").encode() + good + f"\r\n--{boundary}--\r\n".encode()
    line = b"155000.1 463000.2 3.3\n"
    return [
        Case("http/json-content-type", good, {"Content-Type": "application/json"}),
        Case("http/las-content-type-on-xyz", good, {"Content-Type": "application/vnd.las"}),
        Case("http/multipart-form", multipart, {"Content-Type": f"multipart/form-data; boundary={boundary}"}),
        Case("http/gzip-encoded-xyz", gzip.compress(good), {"Content-Encoding": "gzip"}),
        Case("http/gzip-bomb-64MiB", bomb, {"Content-Encoding": "gzip"}),
        Case("http/br-encoded-claim", good, {"Content-Encoding": "br"}),
        Case("http/gzip-laz-unencoded", gzip.compress(laz)),
        Case("http/length-over-limit-claimed", b"0 0 0\n" * 10, transport="lying-length",
             repeat=1 << 40),
        Case("http/length-short-body", laz[:5000], transport="lying-length", repeat=len(laz)),
        Case(f"http/chunked-{chunked_mib}MiB-xyz", None, transport="chunked",
             chunk=line * 4096, repeat=(chunked_mib << 20) // (len(line) * 4096) + 1),
        Case("meta/species-nul", good, query="species=Betula%00pendula"),
        Case("meta/crs-nul", good, query="crs=EPSG%3A28992%00"),
        Case("meta/source-nul", good, query="source=%00"),
        Case("meta/external-id-nul", good, query="external_id=NL%00-1"),
        Case("meta/species-10KiB", good, query="species=" + "Q" * 10240),
        Case("meta/invalid-utf8-species", good, query="species=%FF%FE"),
        Case("meta/acquired-feb-30", good, query="acquired=2024-02-30"),
        Case("meta/mode-unknown", good, query="mode=sideways"),
        Case("meta/wait-not-bool", good, query="wait=maybe"),
        Case("meta/wait-true-four-points", b"0 0 0\n0 0 1\n0 0 2\n1 1 1\n", query="wait=true"),
        Case("meta/wait-true-identical-points", b"1 1 1\n" * 5000, query="wait=true"),
    ]


def encoding_cases(files: dict[str, bytes]) -> list[Case]:
    """silva's own stored forms posted as if they were clouds: the API takes
    no LsJSON, chain code or skeleton uploads, so these must be refused as
    unreadable clouds, never half-read."""
    lsjson = files["tree.lsjson"]
    return [
        Case("other/skeleton-json", files["skeleton.json"]),
        Case("other/lsjson", lsjson),
        Case("other/lsjson-truncated", lsjson[: len(lsjson) // 2]),
        Case("other/chaincode", files["tree.chain"]),
        Case("other/chaincode-with-xyz-tail", files["tree.chain"] + b"\n0 0 0\n"),
    ]


def baseline_rescans(las: bytes, laz: bytes) -> list[Case]:
    """Hostile rescans of the baseline tree: refused or failed, never
    replacing or damaging its stored model."""
    return [
        Case("rescan/nan", b"0 0 0\n1 nan 2\n", targets_baseline=True),
        Case("rescan/four-points", b"0 0 0\n0 0 1\n0 0 2\n1 1 1\n", targets_baseline=True),
        Case("rescan/truncated-laz", laz[: len(laz) // 2], targets_baseline=True),
        Case("rescan/identical-points", b"5 5 5\n" * 5000, targets_baseline=True),
    ]


# ---------------------------------------------------------------- running


def upload_routes(client: Client) -> list[str]:
    """Every POST route of the OpenAPI document with a request body."""
    status, spec = client.get_json("/openapi.json")
    if status != 200:
        sys.exit(f"GET /openapi.json answered {status}")
    return sorted(path for path, item in spec["paths"].items()
                  if "requestBody" in item.get("post", {}))


def send(client: Client, route: str, case: Case, query: str):
    path = route + ("?" + query if query else "")
    headers = {"Content-Type": "application/octet-stream", **case.headers}
    if case.transport == "chunked":
        return client.chunked(path, case.chunk, case.repeat, headers)
    if case.transport == "lying-length":
        return client.lying_length(path, case.body or b"", case.repeat, headers)
    return client.request("POST", path, case.body, headers)


def follow_job(client: Client, location: str, deadline: float) -> tuple[str, str]:
    path = urllib.parse.urlsplit(location).path
    while time.monotonic() < deadline:
        status, job = client.get_json(path)
        if status != 200:
            return f"GET job {status}", ""
        if job["state"] in ("succeeded", "failed"):
            return job["state"], job.get("error") or ""
        time.sleep(0.2)
    return "unfinished", ""


def run_case(client: Client, route: str, case: Case, timeout: float,
             baseline_query: str) -> Result:
    r = Result(case.name, route)
    query = "&".join(q for q in (case.query, baseline_query if case.targets_baseline else "") if q)
    started = time.monotonic()
    try:
        status, headers, body = send(client, route, case, query)
    except (TimeoutError, OSError, http.client.HTTPException) as e:
        r.seconds = time.monotonic() - started
        r.flags.append(f"no answer: {type(e).__name__}: {e}")
        return r
    r.status, r.content_type = status, headers.get("content-type", "")
    if status >= 400:
        try:
            problem = json.loads(body)
            r.title, r.detail = problem.get("title", ""), problem.get("detail", "")
        except ValueError:
            r.detail = body[:120].decode("utf-8", "replace")
        if r.content_type != PROBLEM_JSON:
            r.flags.append("error body is not problem+json")
    if status >= 500:
        r.flags.append(f"{status} answer")
    if status == 202 and "location" in headers:
        r.job, r.job_error = follow_job(client, headers["location"], started + timeout)
        if r.job == "unfinished":
            r.flags.append(f"job unfinished after {timeout:.0f} s")
        if any(w in r.job_error.lower() for w in INTERNAL_WORDS):
            r.flags.append("job error reads as a service fault")
    if status == 422 and any(w in r.detail.lower() for w in INTERNAL_WORDS):
        r.flags.append("422 detail reads as a service fault")
    r.seconds = time.monotonic() - started
    if r.seconds > timeout:
        r.flags.append(f"took {r.seconds:.1f} s")
    return r


def upload_baseline(client: Client, route: str, laz: bytes, timeout: float) -> tuple[str, dict]:
    """Uploads the valid synthetic LAZ under a fresh external id and waits
    for its model; returns the rescan query and the tree document."""
    external = f"hostile-baseline-{int(time.time())}"
    query = f"external_id={external}"
    status, headers, body = client.request(
        "POST", f"{route}?{query}&mode=airborne", laz,
        {"Content-Type": "application/octet-stream"})
    if status != 202:
        sys.exit(f"baseline upload answered {status}: {body[:200]!r}")
    state, error = follow_job(client, headers["location"], time.monotonic() + timeout * 4)
    if state != "succeeded":
        sys.exit(f"baseline job {state}: {error}")
    tree_id = json.loads(body)["tree_id"]
    _, tree = client.get_json(f"/v1/trees/{tree_id}")
    return query, tree


def check_baseline(client: Client, tree: dict, rescan_results: list[Result]) -> list[str]:
    """The baseline tree keeps a downloadable model; it only changes when a
    hostile rescan's job succeeded (a legitimate replacement)."""
    problems = []
    status, now = client.get_json(f"/v1/trees/{tree['id']}")
    if status != 200:
        return [f"baseline tree answers {status}"]
    replaced = any(r.job == "succeeded" for r in rescan_results)
    if now.get("model_id") != tree.get("model_id") and not replaced:
        problems.append("baseline model changed although every hostile rescan failed")
    status, _, _ = client.request("GET", f"/v1/trees/{tree['id']}/skeleton")
    if status != 200:
        problems.append(f"baseline skeleton answers {status}")
    return problems


def log_offset(path: str | None) -> int:
    return os.path.getsize(path) if path and os.path.exists(path) else 0


def log_faults(path: str | None, offset: int) -> list[str]:
    """Panic and internal-error lines the server logged since `offset`."""
    if not path:
        return []
    with open(path, "rb") as f:
        f.seek(offset)
        text = f.read().decode("utf-8", "replace")
    return [line for line in text.splitlines()
            if "panicked" in line or "internal error" in line or "ERROR" in line]


def print_row(r: Result) -> None:
    detail = (r.detail[:70] + "…") if len(r.detail) > 70 else r.detail
    job = f"{r.job}: {r.job_error[:60]}" if r.job else ""
    flag = "  <<< " + "; ".join(r.flags) if r.flags else ""
    print(f"{r.case:38} {r.status!s:>4} {r.content_type[:24]:24} {r.seconds:6.2f}s "
          f"{r.title[:20]:20} {detail:72} {job}{flag}", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base-url", required=True, help="e.g. http://127.0.0.1:18080")
    ap.add_argument("--silva", required=True, help="silva binary, for `silva synth`")
    ap.add_argument("--server-log", help="the server's log file, scanned for panics")
    ap.add_argument("--api-key", help="Bearer key for write routes")
    ap.add_argument("--timeout", type=float, default=30.0, help="per request and per job (s)")
    ap.add_argument("--chunked-mib", type=int, default=300,
                    help="size of the chunked flood; set above the server's body limit")
    ap.add_argument("--only", help="run only cases whose name contains this")
    ap.add_argument("--json", help="write all results to this file")
    args = ap.parse_args()

    client = Client(args.base_url, args.api_key, args.timeout)
    rng = np.random.default_rng(2026)
    with tempfile.TemporaryDirectory() as work:
        files = synth_files(args.silva, work)
    las, laz = files["tree.las"], files["tree.laz"]
    cases = (xyz_cases(rng) + geometry_cases(rng) + ply_cases(rng) + las_cases(las, rng) + laz_cases(laz, rng)
             + transport_cases(las, laz, rng, args.chunked_mib) + encoding_cases(files)
             + baseline_rescans(las, laz))
    if args.only:
        cases = [c for c in cases if args.only in c.name]
    routes = upload_routes(client)
    print(f"{len(cases)} cases x {len(routes)} upload route(s): {', '.join(routes)}")

    offset = log_offset(args.server_log)
    baseline_query, baseline = upload_baseline(client, routes[0], laz, args.timeout)
    results = []
    for route in routes:
        for case in cases:
            r = run_case(client, route, case, args.timeout, baseline_query)
            print_row(r)
            results.append(r)

    summary = []
    status, _, _ = client.request("GET", "/healthz")
    if status != 200:
        summary.append(f"server unhealthy afterwards: /healthz {status}")
    summary += check_baseline(client, baseline, [r for r in results if r.case.startswith("rescan/")])
    summary += [f"server log: {line[:200]}" for line in log_faults(args.server_log, offset)]
    flagged = [r for r in results if r.flags]
    statuses: dict[str, int] = {}
    for r in results:
        statuses[str(r.status)] = statuses.get(str(r.status), 0) + 1
    jobs: dict[str, int] = {}
    for r in results:
        if r.job:
            jobs[r.job] = jobs.get(r.job, 0) + 1
    print(f"\n{len(results)} requests; statuses {statuses}; jobs {jobs}; "
          f"{len(flagged)} flagged cases; {len(summary)} service-level findings")
    for r in flagged:
        print(f"FLAG {r.case} on {r.route}: {'; '.join(r.flags)}")
    for line in summary:
        print(f"FLAG {line}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump([r.__dict__ for r in results] + [{"service": summary}], f, indent=1)
    return 1 if flagged or summary else 0


if __name__ == "__main__":
    sys.exit(main())
