"""Rendered frames are data: a content-addressed on-disk cache of each scenario instance's frames.

A *scenario instance* (the resolved scenario — every override and grid value applied, seed,
camera and render options included — and a frame count) is simulated and rendered once; its
frames, ground truth and camera are stored and fed to every run that shares them.
:meth:`FrameCache.frames` has the contract of :func:`harness.run.frame_feed.rendered_frames`. Key,
entry format, atomic writes, checked reads and the size limit: docs/sweeps.md (frame cache).
"""

from __future__ import annotations

import errno
import fcntl
import functools
import hashlib
import json
import os
import shutil
import socket
import sys
import time
import uuid
import zlib
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path
from typing import IO, Any

import numpy as np

from harness.world.scenario import Scenario
from harness.world.truth import FrameTruth
from monorarp.core.errors import UserError
from monorarp.core.types import Frame

#: Bump whenever rendering, simulation or ground truth change what a frame or its truth holds
#: (the source digest catches edits of :data:`CODE_FILES`; this covers everything else).
RENDERER_VERSION = 1
FORMAT = 1
ZLIB_LEVEL = 1
DEFAULT_MAX_GB = 10.0
ENV_DIR = "MONORARP_CACHE_DIR"
#: Packages whose version changes frames or truth.
PACKAGES = ("highway-env", "gymnasium", "pyrender", "trimesh", "PyOpenGL", "numpy", "opencv-contrib-python-headless")
#: Source files (relative to the repository root) whose content is part of the key.
CODE_FILES = ("harness/render/*.py", "harness/simulation/*.py", "harness/world/ground_truth.py", "harness/world/truth.py",
              "harness/world/state.py", "harness/world/scenario.py", "monorarp/core/camera.py", "monorarp/risk/ttc.py")
MANIFEST, FRAMES, TRUTH, CAMERA = "manifest.json", "frames.bin", "truth.jsonl", "camera.json"
STALE_TMP_S = 24 * 3600.0      # a temporary entry untouched this long (s) is abandoned, whoever wrote it


class CacheError(UserError, OSError):
    """A ``--cache`` directory that cannot be used."""


class _Corrupt(ValueError):
    pass


# -------------------------------------------------------------------------------- key
def default_dir() -> Path:
    """``$MONORARP_CACHE_DIR``, else ``$XDG_CACHE_HOME/monorarp/frames``, else ``~/.cache/monorarp/frames``."""
    env = os.environ.get(ENV_DIR, "").strip()
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME", "").strip()
    return (Path(base) if base else Path.home() / ".cache") / "monorarp" / "frames"


@functools.cache
def code_digest() -> str:
    """sha256 over the source of :data:`CODE_FILES` (paths and bytes), computed once per process."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for pattern in CODE_FILES:
        for f in sorted(root.glob(pattern)):
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


@functools.cache
def package_versions() -> dict[str, str]:
    out = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out


def key_material(scenario: Scenario, n_frames: int) -> dict[str, Any]:
    """Everything that determines the frames and truth of ``n_frames`` of ``scenario``."""
    from harness.render.renderer import gl_identity

    return {"format": FORMAT, "renderer_version": RENDERER_VERSION, "frames": int(n_frames),
            "scenario": scenario.model_dump(mode="json"), "code": code_digest(), "packages": package_versions(),
            "python": "%d.%d" % sys.version_info[:2], "gl": gl_identity()}


def cache_key(material: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(material, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


# ------------------------------------------------------------------------------ cache
class FrameCache:
    """The cache under ``root``; ``max_bytes`` (bytes; None: unlimited) bounds its entries' total size.

    ``lock_wait_s`` (s): how long a process waits for another that renders the same instance
    before rendering it too. ``last``: ``"hit"`` or ``"rendered"``, for the latest :meth:`frames`.
    """

    def __init__(self, root: str | Path, max_bytes: int | None = int(DEFAULT_MAX_GB * 1e9),
                 lock_wait_s: float = 900.0) -> None:
        self.root = Path(root).expanduser()
        self.max_bytes = max_bytes
        self.lock_wait_s = lock_wait_s
        self.last: str | None = None

    # ---------------------------------------------------------------- public
    def frames(self, scenario: Scenario, n_frames: int) -> Iterator[tuple[Frame, FrameTruth]]:
        """(Frame, truth) of each of the ``n_frames`` frames of ``scenario``, from the cache or rendered.

        As :func:`harness.run.frame_feed.rendered_frames`, scenario errors raise here, before any frame.
        """
        material = key_material(scenario, n_frames)
        key = cache_key(material)
        self.last = "hit"
        hit = self._open(key)
        if hit is not None:
            return hit
        lock = self._lock(key)
        try:
            hit = self._open(key)           # made by another process while we waited for the lock
            if hit is not None:
                _unlock(lock)
                return hit
            from harness.run import frame_feed

            source = frame_feed.rendered_frames(scenario, n_frames)
        except BaseException:
            _unlock(lock)
            raise
        self.last = "rendered"
        return self._store(key, material, scenario, source, lock)

    def entry_dir(self, key: str) -> Path:
        return self.root / "entries" / key[:2] / key

    def entries(self) -> list[tuple[float, int, Path]]:
        """(last use as a POSIX time, bytes, directory) of every complete entry."""
        out = []
        base = self.root / "entries"
        for shard in _listdir(base):
            for d in _listdir(base / shard):
                path = base / shard / d
                try:
                    used = (path / MANIFEST).stat().st_mtime
                    size = sum((path / f).stat().st_size for f in os.listdir(path))
                except OSError:
                    continue
                out.append((used, size, path))
        return out

    def evict(self, keep: str | None = None) -> int:
        """Remove least recently used entries until the total is at most ``max_bytes`` (never ``keep``),
        and abandoned temporary entries; returns the number of entries removed."""
        self._clean_tmp()
        if self.max_bytes is None:
            return 0
        entries = sorted(self.entries())
        total = sum(size for _, size, _ in entries)
        removed = 0
        for _, size, path in entries:
            if total <= self.max_bytes:
                break
            if path.name == keep:
                continue
            self._discard(path)
            (self.root / "locks" / f"{path.name}.lock").unlink(missing_ok=True)
            total -= size
            removed += 1
        return removed

    # ----------------------------------------------------------------- reads
    def _open(self, key: str) -> Iterator[tuple[Frame, FrameTruth]] | None:
        """The entry's frames after checking every file, or None (no entry; a bad one is removed)."""
        d = self.entry_dir(key)
        if not d.is_dir():
            return None
        f: IO[bytes] | None = None
        try:
            manifest = json.loads((d / MANIFEST).read_bytes())
            if manifest.get("format") != FORMAT or manifest.get("key") != key:
                raise _Corrupt("manifest of another format or key")
            files = manifest["files"]
            for name in (TRUTH, CAMERA):
                _check(name, (d / name).read_bytes(), files[name])
            f = open(d / FRAMES, "rb")
            h, n = hashlib.sha256(), 0
            while chunk := f.read(1 << 22):
                h.update(chunk)
                n += len(chunk)
            _check_digest(FRAMES, n, h.hexdigest(), files[FRAMES])
            truths = [FrameTruth.from_json(json.loads(line)) for line in (d / TRUTH).read_bytes().splitlines()]
            sizes = [int(s) for s in manifest["frame_bytes"]]
            if not len(truths) == len(sizes) == int(manifest["frames"]) or sum(sizes) != n:
                raise _Corrupt("frame count or sizes disagree")
            shape, dtype = tuple(int(x) for x in manifest["shape"]), np.dtype(manifest["dtype"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            if f is not None:
                f.close()
            self._discard(d)
            return None
        try:
            os.utime(d / MANIFEST)              # last use, for the LRU eviction
        except OSError:
            pass
        return _replay(f, sizes, truths, shape, dtype)

    # ---------------------------------------------------------------- writes
    def _store(self, key: str, material: dict, scenario: Scenario, source: Iterator[tuple[Frame, FrameTruth]],
               lock: int | None) -> Iterator[tuple[Frame, FrameTruth]]:
        writer: _EntryWriter | None = None
        try:
            try:
                writer = _EntryWriter(self.root / "tmp", key)
            except OSError:
                writer = None
            for frame, truth in source:
                if writer is not None and not writer.add(frame.image, truth):
                    writer.abort()
                    writer = None
                yield frame, truth
            if writer is not None and writer.commit(self.entry_dir(key), material,
                                                    scenario.camera.model().to_dict()):
                try:
                    self.evict(keep=key)
                except OSError:
                    pass
        finally:
            if writer is not None:
                writer.abort()
            getattr(source, "close", lambda: None)()     # frees the renderer now if the run stopped early
            _unlock(lock)

    def _lock(self, key: str) -> int | None:
        """An exclusive ``flock`` on ``locks/<key>.lock`` (waits up to ``lock_wait_s``), or None."""
        try:
            (self.root / "locks").mkdir(parents=True, exist_ok=True)
            fd = os.open(self.root / "locks" / f"{key}.lock", os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:
            return None
        deadline = time.monotonic() + self.lock_wait_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return fd
            except BlockingIOError:
                if time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            except OSError:              # e.g. ENOLCK on a filesystem without locks
                break
        os.close(fd)
        return None

    def _discard(self, path: Path) -> None:
        """Remove an entry or temporary directory: renamed away first, so it disappears at once."""
        trash = self.root / "tmp" / f"trash-{uuid.uuid4().hex}"
        try:
            trash.parent.mkdir(parents=True, exist_ok=True)
            os.rename(path, trash)
        except OSError:
            return
        shutil.rmtree(trash, ignore_errors=True)

    def _clean_tmp(self) -> None:
        """Remove what killed writers left in ``tmp/``: theirs when their process is gone, anyone's after a day."""
        tmp, host, now = self.root / "tmp", socket.gethostname(), time.time()
        for name in _listdir(tmp):
            path = tmp / name
            try:
                age = now - path.stat().st_mtime
            except OSError:
                continue
            parts = name.partition(".")[2].rsplit(".", 2)       # <key>.<host>.<pid>.<random>
            dead = len(parts) == 3 and parts[0] == host and parts[1].isdigit() and not _pid_alive(int(parts[1]))
            if name.startswith("trash-") or dead or age > STALE_TMP_S:
                if path.is_dir():
                    shutil.rmtree(path, ignore_errors=True)
                else:
                    path.unlink(missing_ok=True)


class _EntryWriter:
    """Builds one entry in a private temporary directory while frames are rendered."""

    def __init__(self, tmp_root: Path, key: str) -> None:
        tmp_root.mkdir(parents=True, exist_ok=True)
        self.dir = tmp_root / f"{key}.{socket.gethostname()}.{os.getpid()}.{uuid.uuid4().hex[:8]}"
        self.dir.mkdir()
        self.key = key
        self._frames = open(self.dir / FRAMES, "wb")
        self._truth = open(self.dir / TRUTH, "wb")
        self._h = {FRAMES: hashlib.sha256(), TRUTH: hashlib.sha256()}
        self._n = {FRAMES: 0, TRUTH: 0}
        self.sizes: list[int] = []
        self.shape: tuple[int, ...] | None = None
        self.dtype: str | None = None

    def _write(self, name: str, f: IO[bytes], data: bytes) -> None:
        f.write(data)
        self._h[name].update(data)
        self._n[name] += len(data)

    def add(self, image: np.ndarray, truth: FrameTruth) -> bool:
        """Append one frame; False when it cannot be stored (the entry is then abandoned)."""
        if self.shape is None:
            self.shape, self.dtype = tuple(image.shape), image.dtype.str
        if tuple(image.shape) != self.shape or image.dtype.str != self.dtype:
            return False
        try:
            blob = zlib.compress(np.ascontiguousarray(image).tobytes(), ZLIB_LEVEL)
            self._write(FRAMES, self._frames, blob)
            self._write(TRUTH, self._truth, (json.dumps(truth.to_json(), separators=(",", ":")) + "\n").encode())
        except (OSError, TypeError, ValueError):
            return False
        self.sizes.append(len(blob))
        return True

    def commit(self, final: Path, material: dict, camera: dict) -> bool:
        """Close the files, write camera and manifest, rename into ``final``. True when this entry is there now."""
        try:
            self._frames.close()
            self._truth.close()
            cam = (json.dumps(camera, indent=2) + "\n").encode()
            (self.dir / CAMERA).write_bytes(cam)
            files = {FRAMES: _digest(self._n[FRAMES], self._h[FRAMES].hexdigest()),
                     TRUTH: _digest(self._n[TRUTH], self._h[TRUTH].hexdigest()),
                     CAMERA: _digest(len(cam), hashlib.sha256(cam).hexdigest())}
            manifest = {"format": FORMAT, "key": self.key, "frames": len(self.sizes),
                        "shape": list(self.shape or ()), "dtype": self.dtype or "|u1",
                        "compression": f"zlib-{ZLIB_LEVEL}", "frame_bytes": self.sizes, "files": files,
                        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "material": material}
            (self.dir / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
            final.parent.mkdir(parents=True, exist_ok=True)
            os.rename(self.dir, final)
        except OSError as e:
            if e.errno in (errno.ENOTEMPTY, errno.EEXIST):   # another process stored it first: same content
                self.abort()
            return False
        self.dir = None
        return True

    def abort(self) -> None:
        for f in (self._frames, self._truth):
            f.close()
        if self.dir is not None:
            shutil.rmtree(self.dir, ignore_errors=True)
            self.dir = None


# ---------------------------------------------------------------------------- helpers
def _replay(f: IO[bytes], sizes: list[int], truths: list[FrameTruth], shape: tuple[int, ...],
            dtype: np.dtype) -> Iterator[tuple[Frame, FrameTruth]]:
    with f:
        f.seek(0)
        for size, truth in zip(sizes, truths):
            image = np.frombuffer(bytearray(zlib.decompress(f.read(size))), dtype=dtype).reshape(shape)
            yield Frame(index=truth.frame, t=truth.t, image=image), truth


def _digest(size: int, sha256: str) -> dict[str, Any]:
    return {"bytes": size, "sha256": sha256}


def _check(name: str, data: bytes, expected: dict) -> None:
    _check_digest(name, len(data), hashlib.sha256(data).hexdigest(), expected)


def _check_digest(name: str, size: int, sha256: str, expected: dict) -> None:
    if size != int(expected["bytes"]) or sha256 != expected["sha256"]:
        raise _Corrupt(f"{name}: size or checksum differs from the manifest")


def _unlock(fd: int | None) -> None:
    if fd is not None:
        os.close(fd)                   # closing the descriptor releases the flock


def _listdir(path: Path) -> list[str]:
    try:
        return sorted(os.listdir(path))
    except OSError:
        return []


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def check_max_gb(max_gb: float | None) -> None:
    """``--cache-max-gb`` checked: a positive finite number of GB, or None (unlimited); :class:`CacheError`."""
    if max_gb is not None and not (max_gb > 0 and max_gb < float("inf")):
        raise CacheError(f"--cache-max-gb: must be a positive number of GB, got {max_gb}")


def open_cache(where: str | Path | None, max_gb: float | None = DEFAULT_MAX_GB) -> FrameCache | None:
    """The cache for ``--cache`` (``None``: :func:`default_dir`; ``"off"``: no cache) and ``--cache-max-gb``
    (GB = 1e9 bytes; None: unlimited). The directory is created and checked to be writable now;
    raises :class:`CacheError` (one line) otherwise."""
    check_max_gb(max_gb)                         # a bad limit is refused with --cache off too
    if isinstance(where, str) and where.strip().lower() == "off":
        return None
    if isinstance(where, str) and not where.strip():
        raise CacheError("--cache: give a directory or 'off'")
    root = default_dir() if where is None else Path(where).expanduser()
    try:
        for sub in ("entries", "tmp", "locks"):
            (root / sub).mkdir(parents=True, exist_ok=True)
        probe = root / "tmp" / f".probe-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as e:
        raise CacheError(f"--cache {root}: cannot use it as a frame cache ({e.strerror or e}); "
                         f"give another directory or --cache off") from None
    return FrameCache(root.resolve(), None if max_gb is None else int(max_gb * 1e9))
