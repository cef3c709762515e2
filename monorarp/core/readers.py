"""Reading user-supplied text files (YAML configs, camera files, JSON results) without surprises.

Every reader of a file the user names goes through here, so that whatever the
file holds -- binary bytes, text that is not UTF-8, a document nested thousands
of levels deep, a YAML alias bomb, a ``!!python/object`` tag, a gigabyte of
anything -- the result is either the parsed document or one ``error(message)``
naming the file and the reason (the CLI prints it as one line and exits 2),
never a traceback and never unbounded memory or time:

* :func:`read_text` -- at most ``max_bytes`` (size checked before reading),
  strict UTF-8 (a leading BOM is dropped), OS errors (missing file, directory,
  permission, name too long) reported with their reason (:func:`path_problem`).
* :func:`path_problem` -- the true reason a path cannot be read as a file (or directory): a
  directory, a broken symbolic link, a link loop, a file where a directory belongs, missing.
* :func:`parse_yaml` -- YAML 1.1 *safe* subset restricted to JSON types: mappings,
  sequences, strings, numbers, booleans, null. A key given twice in one mapping is refused. Tags that build other types
  (``!!python/*``, ``!!binary``, ``!!set``, ``!!omap``, ``!!pairs``, ``!!timestamp``)
  are refused; unquoted dates stay strings; integers have at most :data:`MAX_INT_BITS`
  bits. Nesting is limited to
  :data:`MAX_DEPTH` levels and the document, with every alias expanded, to
  :data:`MAX_NODES` values (a "billion laughs" document is refused before it
  is expanded); recursive aliases are refused.
* :func:`parse_json` -- :func:`json.loads` with over-long integers, nesting
  deeper than :data:`MAX_DEPTH` and a key given twice in one object (json keeps the last) reported as errors.
* :func:`read_yaml`, :func:`read_json` -- a file the user names, read and parsed.
* :func:`read_json_or_none` -- a JSON file this program wrote (a run's ``metrics.json``):
  ``None`` when it is missing, unreadable or not JSON, for callers that treat that as "not there".
"""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, SequenceNode

from monorarp.core.errors import UserError

#: Largest YAML config file read (scenario, sweep spec, protocol, camera): configs are a few kB, and the
#: pure-Python YAML parser (the only one that can limit nesting safely) reads about 100 kB/s at worst.
MAX_CONFIG_BYTES = 256 << 10
#: Largest JSON results file read (``metrics.json``, ``summary.json``, baselines).
MAX_JSON_BYTES = 256 << 20
#: Deepest nesting of mappings/sequences accepted in a YAML config or a JSON file.
MAX_DEPTH = 64
#: Most values (mapping keys and values, sequence items, scalars) in a YAML document, aliases expanded.
MAX_NODES = 100_000
#: Largest integer in a YAML config (Python cannot even print one of 4,300 digits by default).
MAX_INT_BITS = 256


# ------------------------------------------------------------------------ paths
def path_problem(path: str | Path, want: str = "file") -> str | None:
    """Why ``path`` cannot be opened as a ``want`` ("file" or "directory"), or None when it can: "is a
    directory", "not a directory", "broken symbolic link to T", "symbolic link loop", "not a directory:
    P" (a file P where a directory of the path belongs), "no such file", "no such directory", or the OS's
    words (permission, name too long). Every reader of a path the user names reports this, never a guess."""
    path = Path(path)
    try:
        os.stat(path)
    except OSError as e:
        return _stat_problem(path, e, want)
    except ValueError as e:          # an embedded NUL byte
        return str(e)
    is_dir = os.path.isdir(path)
    if want == "file" and is_dir:
        return "is a directory"
    if want == "directory" and not is_dir:
        return "not a directory"
    if not os.access(path, os.R_OK | (os.X_OK if is_dir else 0)):
        return "permission denied"
    return None


def _stat_problem(path: Path, e: OSError, want: str) -> str:
    """The reason of ``os.stat(path)``'s error ``e``, told apart by looking at the link and the parents."""
    if e.errno == errno.ELOOP:
        return "symbolic link loop"
    if e.errno == errno.ENOENT and os.path.islink(path):
        return f"broken symbolic link to {os.readlink(path)}"
    if e.errno in (errno.ENOENT, errno.ENOTDIR):
        for parent in reversed(path.parents):       # the first part of the path that is not a directory
            if os.path.lexists(parent) and not os.path.isdir(parent):
                return f"not a directory: {parent.name}" if os.path.exists(parent) else _stat_reason(parent)
            if not os.path.lexists(parent):
                break
        return "no such directory" if want == "directory" else "no such file"
    return e.strerror or type(e).__name__


def _stat_reason(parent: Path) -> str:
    try:
        os.stat(parent)
    except OSError as e:
        return f"{parent.name}: {'symbolic link loop' if e.errno == errno.ELOOP else 'broken symbolic link'}"
    return "no such file"


# ------------------------------------------------------------------------ text
def read_text(path: str | Path, what: str, error: type[Exception] = UserError,
              max_bytes: int = MAX_CONFIG_BYTES) -> str:
    """The UTF-8 text of ``path``; anything else raises ``error("PATH: reason")``."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            st = os.fstat(f.fileno())
            if st.st_size > max_bytes:
                raise error(f"{path}: {what} too large ({_size(st.st_size)}; at most {_size(max_bytes)})")
            data = f.read(max_bytes + 1)   # a pipe or a growing file has no trustworthy size
    except OSError as e:
        reason = path_problem(path) or e.strerror or type(e).__name__
        raise error(f"{path}: cannot read {what} ({reason})") from None
    except ValueError as e:   # e.g. an embedded NUL byte in the path
        raise error(f"{path!r}: cannot read {what} ({e})") from None
    if len(data) > max_bytes:
        raise error(f"{path}: {what} too large (more than {_size(max_bytes)})")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise error(f"{path}: {what} is not UTF-8 text (byte 0x{data[e.start]:02x} at line {line}, "
                    f"offset {e.start}); binary file?") from None
    text = text.removeprefix("\ufeff")
    if "\x00" in text:
        raise error(f"{path}: {what} is not a text file (holds NUL bytes)")
    return text


def _size(n: int) -> str:
    return f"{n / (1 << 20):.1f} MiB" if n >= 1 << 20 else f"{n} bytes"


# ------------------------------------------------------------------------ YAML
class _LimitError(yaml.YAMLError):
    def __init__(self, problem: str, mark: Any = None) -> None:
        super().__init__(problem)
        self.problem, self.problem_mark = problem, mark


class _ConfigLoader(yaml.SafeLoader):
    """SafeLoader producing JSON types only, with nesting depth limited while composing."""

    _depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _LimitError(f"nested more than {MAX_DEPTH} levels deep", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        """As SafeLoader's, refusing a key given twice in one mapping (YAML says keys are unique; PyYAML
        would keep the last). Keys brought in by a merge (``<<: *base``) may be overridden, as YAML says."""
        if isinstance(node, MappingNode):
            first: dict[Any, Any] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=False)
                try:
                    earlier = first.get(key)
                except TypeError:   # an unhashable key: SafeLoader reports it
                    continue
                if earlier is not None:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first at line {earlier.start_mark.line + 1})",
                        key_node.start_mark)
                first[key] = key_node
        return super().construct_mapping(node, deep=deep)


def _refuse_tag(loader: yaml.SafeLoader, node: Any) -> Any:
    raise yaml.constructor.ConstructorError(None, None, f"YAML tag {node.tag!r} is not allowed in a config file "
                                            "(only mappings, lists, strings, numbers, booleans, null)",
                                            node.start_mark)


def _bounded_int(loader: yaml.SafeLoader, node: Any) -> int:
    value = yaml.SafeLoader.construct_yaml_int(loader, node)
    if value.bit_length() > MAX_INT_BITS:   # 0xfff... of 5,000 digits: no config value, and unprintable
        raise yaml.constructor.ConstructorError(None, None, f"integer of more than {MAX_INT_BITS} bits",
                                                node.start_mark)
    return value


_ConfigLoader.add_constructor("tag:yaml.org,2002:int", _bounded_int)
for _tag in ("binary", "timestamp", "omap", "pairs", "set"):
    _ConfigLoader.add_constructor(f"tag:yaml.org,2002:{_tag}", _refuse_tag)
# Unquoted dates (2024-01-01) stay strings instead of becoming datetime objects.
_ConfigLoader.yaml_implicit_resolvers = {
    k: [(tag, rx) for tag, rx in v if tag != "tag:yaml.org,2002:timestamp"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}


def _expanded_size(root: Any) -> int:
    """Number of nodes of the composed graph with every alias expanded (iterative; refuses cycles)."""
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            total = 1 + sum(size[id(c)] for c in _children(node))
            size[key] = total
            if total > MAX_NODES:
                raise _LimitError(f"more than {MAX_NODES} values once aliases are expanded "
                                  f"(an alias bomb?)", node.start_mark)
            continue
        if key in size:
            continue
        if key in on_path:
            raise _LimitError("recursive alias (a node that contains itself)", node.start_mark)
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in _children(node) if id(c) not in size)
    return size[id(root)]


def _children(node: Any) -> list:
    if isinstance(node, SequenceNode):
        return list(node.value)
    if isinstance(node, MappingNode):
        return [n for kv in node.value for n in kv]
    return []


def parse_yaml(text: str, source: str | Path, error: type[Exception] = UserError) -> Any:
    """The document in ``text`` (JSON types; empty document -> None); ``error`` naming ``source`` otherwise."""
    loader = None
    try:
        loader = _ConfigLoader(text)   # the reader refuses control characters here
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node)
        return loader.construct_document(node)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        reason = getattr(e, "problem", None) or str(e)
        raise error(f"{source}: invalid YAML{where}: {reason}") from None
    except RecursionError:   # a last guard; MAX_DEPTH stops nesting long before
        raise error(f"{source}: invalid YAML: nested too deeply") from None
    except Exception as e:  # noqa: BLE001 - constructors raise what they like: int('9' * 5000), '!!bool maybe'
        raise error(f"{source}: invalid YAML: {type(e).__name__}: {_first_line(e)}") from None
    finally:
        if loader is not None:
            loader.dispose()


def read_yaml(path: str | Path, what: str, error: type[Exception] = UserError) -> Any:
    """The parsed YAML file ``path`` (limits above); unreadable or malformed files raise ``error``."""
    return parse_yaml(read_text(path, what, error), path, error)


# ------------------------------------------------------------------------ JSON
class _DuplicateKey(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _unique_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` of :func:`parse_json`: a JSON object as a dict, refusing a key given twice
    (``json.loads`` would keep the last one silently, as PyYAML would; see :class:`_ConfigLoader`)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def parse_json(text: str, source: str | Path, what: str = "file", error: type[Exception] = UserError) -> Any:
    """``json.loads(text)``; malformed, too deeply nested, over-long numbers or a key given twice in one
    object raise ``error``."""
    try:
        data = json.loads(text, object_pairs_hook=_unique_object)
    except _DuplicateKey as e:
        raise error(f"{source}: {what} is not valid JSON (key {e.key!r} given twice in one object)") from None
    except RecursionError:
        raise error(f"{source}: {what} is not valid JSON (nested too deeply)") from None
    except ValueError as e:
        raise error(f"{source}: {what} is not valid JSON ({_first_line(e)})") from None
    if _depth(data) > MAX_DEPTH:   # readers walk documents recursively: refuse what no writer produces
        raise error(f"{source}: {what} is nested more than {MAX_DEPTH} levels deep")
    return data


def read_json(path: str | Path, what: str, error: type[Exception] = UserError,
              max_bytes: int = MAX_JSON_BYTES) -> Any:
    """The parsed JSON file ``path``; unreadable or malformed files raise ``error("PATH: reason")``."""
    return parse_json(read_text(path, what, error, max_bytes), path, what, error)


def read_json_or_none(path: str | Path) -> Any | None:
    """The parsed JSON file ``path``, or ``None`` when it cannot be read or is not JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _depth(data: Any) -> int:
    """Nesting depth of JSON values (iterative): a scalar 0, ``[]`` 1, ``[[1]]`` 2."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        v, d = stack.pop()
        items = v.values() if isinstance(v, dict) else v if isinstance(v, list) else None
        if items is None:
            continue
        deepest = max(deepest, d)
        if deepest > MAX_DEPTH:
            break
        stack.extend((c, d + 1) for c in items)
    return deepest


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return (text.splitlines()[0] if text else type(e).__name__)[:300]
