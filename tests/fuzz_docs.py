"""Hypothesis strategies for malformed input files (shared by tests/test_fuzz_inputs.py).

A generated :class:`Doc` is either file content (bytes) or a file-system oddity
(missing, a directory, a name too long, a symlink loop). Content comes from:

* **mutations of a valid document** -- 1 to 4 edits at random places of a valid
  mapping: a value replaced by junk (wrong type, NaN/inf, extreme numbers, odd
  strings, deep lists), a key deleted, an unknown key added, a value wrapped in
  a list -- serialised as block or flow YAML or as JSON;
* **arbitrary JSON-like values** (any shape, with the reader's real key names);
* **byte-level corruption** of a valid document (truncation, inserted/flipped
  bytes, other encodings, BOMs, NUL bytes);
* **pathological documents**: nesting 65 to 20,000 levels deep, alias bombs and
  recursive aliases, YAML tags (``!!python/object``, ``!!binary``, ``!!set``,
  ``!!bool maybe``, ...), several documents in one file, binary data with real
  magic numbers, files larger than the readers' limits.

A reader that accepts almost any JSON (``metrics.json``, ``summary.json``, ``run.json``)
gets ``documents(..., breaks=...)``: the same kinds of defects, each made invalid by
construction (:func:`broken_json`, the ``strict_json`` corruptions, edge texts that are
not JSON), so that nearly every generated document is one the reader must refuse.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from hypothesis import strategies as st

from monorarp.core.readers import MAX_CONFIG_BYTES, MAX_DEPTH


@dataclass(frozen=True)
class Doc:
    """One generated input: ``kind`` "bytes" (``data`` is the content) or a file-system oddity."""

    kind: str
    data: bytes = b""
    label: str = ""

    def __repr__(self) -> str:   # hypothesis prints this for a failing example
        shown = self.data[:300] + (b"..." if len(self.data) > 300 else b"")
        return f"Doc({self.kind!r}, {self.label!r}, {len(self.data)} bytes: {shown!r})"


FS_KINDS = ("missing", "directory", "long_name", "symlink_loop", "dangling_symlink")


def materialise(doc: Doc, directory: Path, name: str) -> Path:
    """Write ``doc`` as ``directory/name`` (or create the oddity it describes); returns the path to give."""
    path = directory / name
    if doc.kind == "bytes":
        path.write_bytes(doc.data)
    elif doc.kind == "sparse":            # a huge file without the disk cost: size from the label
        with open(path, "wb") as f:
            f.truncate(int(doc.label.split("=")[1]))
    elif doc.kind == "missing":
        pass
    elif doc.kind == "directory":
        path.mkdir()
    elif doc.kind == "long_name":
        path = directory / ("x" * 300 + Path(name).suffix)
    elif doc.kind == "symlink_loop":
        os.symlink(path.name, path)
    elif doc.kind == "dangling_symlink":
        os.symlink(directory / "nowhere" / name, path)
    else:
        raise ValueError(doc.kind)
    return path


# ----------------------------------------------------------------------- values
ODD_STRINGS = ["", " ", "\t", "null", "~", "yes", "no", "on", "NaN", ".nan", ".inf", "-.inf", "1e999", "-0",
               "0x1F", "0o17", "1_000", "2024-01-01", "12:30:00", "../../etc/passwd", "/dev/zero", "é", "\u202e",
               "\ud7ff", "\U0001f697", "a" * 500, "%s%s%n", "{{x}}", "${HOME}", "*", "&", "!", "|", ">",
               "-", "? x", "#", "'", '"', "\\", "\r\n", "\x0b", "car\x1bred"]
EXTREME_NUMBERS = [0, -1, 1, -0.0, 2 ** 31, -2 ** 31, 2 ** 63, -2 ** 63 - 1, 10 ** 30, -10 ** 30, 1e308, -1e308,
                   1.7976931348623157e308, 5e-324, -5e-324, 1e-300, math.nan, math.inf, -math.inf, 0.1, 1e16]

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-(10 ** 40), max_value=10 ** 40),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(EXTREME_NUMBERS),
    st.text(max_size=20), st.sampled_from(ODD_STRINGS),
)


def json_values(keys: list[str]) -> st.SearchStrategy:
    key = st.one_of(st.sampled_from(keys), st.text(max_size=12)) if keys else st.text(max_size=12)
    return st.recursive(scalars, lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(key, inner, max_size=5)), max_leaves=15)


def deep_list(depth: int, leaf: Any = 1) -> Any:
    v = leaf
    for _ in range(depth):
        v = [v]
    return v


def junk(keys: list[str]) -> st.SearchStrategy:
    """A replacement value: mostly scalars, sometimes containers or deep nesting."""
    return st.one_of(scalars, scalars, json_values(keys),
                     st.integers(65, 200).map(deep_list),
                     st.lists(scalars, min_size=0, max_size=3))


# --------------------------------------------------------------------- mutation
def _slots(doc: Any, path: tuple = ()) -> list[tuple]:
    """Every (path to container, key) in ``doc``, plus ``()`` for the root itself."""
    out = [path]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _slots(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _slots(v, path + (i,))
    return out


def _get(doc: Any, path: tuple) -> Any:
    for p in path:
        doc = doc[p]
    return doc


@st.composite
def mutated(draw, base: dict, keys: list[str]) -> Any:
    """``base`` with 1..4 random edits (at least one of which usually makes it invalid)."""
    doc: Any = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 4))):
        slots = _slots(doc)
        path = draw(st.sampled_from(slots))
        op = draw(st.sampled_from(["replace", "replace", "replace", "delete", "extra", "wrap", "extra_nested"]))
        if not path:
            if op == "replace":
                doc = draw(junk(keys))
            elif op == "wrap":
                doc = [doc]
            elif isinstance(doc, dict) and op in ("extra", "extra_nested"):
                doc[draw(st.text(min_size=1, max_size=12))] = draw(scalars)
            continue
        parent, key = _get(doc, path[:-1]), path[-1]
        if op == "replace":
            parent[key] = draw(junk(keys))
        elif op == "delete":
            del parent[key]
        elif op == "wrap":
            parent[key] = [parent[key]]
        elif op == "extra":
            target = parent if isinstance(parent, dict) else None
            if target is not None:
                target[draw(st.text(min_size=1, max_size=12).filter(lambda k: k not in target))] = draw(scalars)
            else:
                parent.append(draw(junk(keys)))
        else:   # extra_nested: an unknown key inside the value, if it is a mapping
            value = parent[key]
            if isinstance(value, dict):
                value[draw(st.sampled_from(keys + ["zzz", "Name", "name ", "__class__"]))] = draw(junk(keys))
            else:
                parent[key] = {draw(st.sampled_from(keys or ["x"])): value}
    return doc


# ------------------------------------------------------------------ serialising
def to_yaml(doc: Any, flow: bool | None) -> bytes:
    return yaml.safe_dump(doc, default_flow_style=flow, allow_unicode=True, sort_keys=False).encode("utf-8")


def to_json(doc: Any, indent: int | None) -> bytes:
    return json.dumps(doc, indent=indent, allow_nan=True).encode("utf-8")


def serialised(docs: st.SearchStrategy, fmt: str) -> st.SearchStrategy:
    if fmt == "json":
        return st.tuples(docs, st.sampled_from([None, 2])).map(lambda t: Doc("bytes", to_json(*t), "json"))
    return st.tuples(docs, st.sampled_from([False, True, None])).map(lambda t: Doc("bytes", to_yaml(*t), "yaml"))


# ------------------------------------------------------------------- corruption
JSON_WHITESPACE = b" \t\r\n"


def _json_tokens(text: bytes) -> tuple[list[int], list[tuple[int, int]]]:
    """Positions of the structural bytes (``{}[]:,`` and string quotes) and the (start, end) of every string
    token of the JSON text ``text``."""
    structural, strings = [], []
    for m in re.finditer(rb'"(?:[^"\\]|\\.)*"|[{}\[\]:,]', text):
        if m.group().startswith(b'"'):
            structural += [m.start(), m.end() - 1]
            strings.append((m.start(), m.end()))
        else:
            structural.append(m.start())
    return structural, strings


@st.composite
def corrupted(draw, valid: bytes, strict_json: bool = False) -> Doc:
    """``valid`` with its bytes damaged. ``strict_json`` (``valid`` is a JSON object, 2-space indented): every
    damage makes it unreadable as JSON -- bytes inserted between a key and its colon, a structural byte changed,
    a BOM or line break JSON does not know, a raw tab inside a string; none that JSON tolerates."""
    data = bytearray(valid)
    op = draw(st.sampled_from(["truncate", "insert", "flip", "utf16", "latin1", "bom", "nul", "surrogate",
                               "crlf", "tabs", "prefix_binary"]))
    pos = draw(st.integers(0, max(len(data) - 1, 0)))
    structural, strings = _json_tokens(valid) if strict_json else ([], [])
    if op == "truncate":
        data = data[:pos]
    elif op == "insert" and strict_json:   # "key"<bytes>: -- anything but whitespace or ':' there is no JSON
        keys = [end for _, end in strings if valid[end:].lstrip(JSON_WHITESPACE).startswith(b":")]
        at = draw(st.sampled_from(keys))
        data[at:at] = draw(st.binary(min_size=1, max_size=16).filter(lambda b: b[:1] not in JSON_WHITESPACE + b":"))
    elif op == "insert":
        data[pos:pos] = draw(st.binary(min_size=1, max_size=16))
    elif op == "flip":
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, max(len(data) - 1, 0)))
            if data:
                data[i] = draw(st.integers(0, 255))
        if strict_json:   # and one structural byte replaced by another value (last, so that none restores it)
            i = draw(st.sampled_from(structural))
            data[i] = (valid[i] + draw(st.integers(1, 255))) % 256
    elif op == "bom" and strict_json:   # the reader drops one UTF-8 BOM (valid), not these
        data[0:0] = draw(st.sampled_from([b"\xff\xfe", b"\xfe\xff", b"\xef\xbb\xbf\xef\xbb\xbf"]))
    elif op == "crlf" and strict_json:  # line breaks that are not JSON whitespace
        data = bytearray(valid.replace(b"\n", draw(st.sampled_from([b"\x85", "\u2028".encode(), b"\x0b", b"\x0c"]))))
    elif op == "tabs" and strict_json:  # JSON strings hold no raw control characters
        start, end = draw(st.sampled_from(strings))
        at = draw(st.integers(start + 1, end - 1))
        data[at:at] = draw(st.sampled_from([b"\t", b"\r", b"\n", b"\x1b"]))
    elif op == "utf16":
        data = bytearray(valid.decode("utf-8").encode(draw(st.sampled_from(["utf-16", "utf-16-le", "utf-32"]))))
    elif op == "latin1":
        data[pos:pos] = "é ÿ ß".encode("latin-1")
    elif op == "bom":
        data[0:0] = draw(st.sampled_from([b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff", b"\xef\xbb\xbf\xef\xbb\xbf"]))
    elif op == "nul":
        data[pos:pos] = b"\x00"
    elif op == "surrogate":
        data[pos:pos] = "\ud800".encode("utf-8", "surrogatepass")
    elif op == "crlf":
        data = bytearray(valid.replace(b"\n", draw(st.sampled_from([b"\r\n", b"\r", b"\x85", "\u2028".encode()]))))
    elif op == "tabs":
        data = bytearray(valid.replace(b"  ", b"\t"))
    else:
        data[0:0] = draw(st.sampled_from(MAGIC))
    return Doc("bytes", bytes(data), f"corrupted:{op}")


MAGIC = [b"\x89PNG\r\n\x1a\n", b"\x7fELF\x02\x01\x01", b"\x1f\x8b\x08", b"PK\x03\x04", b"\x00\x00\x00\x18ftypmp42",
         b"%PDF-1.4\n", b"\xff\xd8\xff\xe0", b"GIF89a", b"\x08\x01\x12\x07pytorch"]


@st.composite
def binary(draw) -> Doc:
    head = draw(st.sampled_from([b""] + MAGIC))
    return Doc("bytes", head + draw(st.binary(max_size=2048)), "binary")


# ------------------------------------------------------------------ pathological
@st.composite
def deep_nesting(draw, fmt: str) -> Doc:
    depth = draw(st.one_of(st.integers(65, 400), st.integers(400, 20_000), st.sampled_from([990, 1000, 3000])))
    style = draw(st.sampled_from(["list", "map", "mixed", "block"] if fmt == "yaml" else ["list", "map", "mixed"]))
    under = draw(st.sampled_from(["", "road", "vehicles", "runs", "tests", "metrics", "K", "grid"]))
    if style == "block":
        depth = min(depth, 300)
        body = "".join(f"{'  ' * i}k:\n" for i in range(depth)) + "  " * depth + "1\n"
        text = body if not under else f"{under}:\n" + "".join("  " + line + "\n" for line in body.splitlines())
        return Doc("bytes", text.encode(), f"deep:{style}:{depth}")
    if style == "list":
        inner = "[" * depth + "1" + "]" * depth
    elif style == "map":
        inner = '{"a": ' * depth + "1" + "}" * depth
    else:
        inner = '[{"a": ' * (depth // 2) + "1" + "}]" * (depth // 2)
    text = inner if not under else f'{{"{under}": {inner}}}'
    return Doc("bytes", text.encode(), f"deep:{style}:{depth}")


@st.composite
def alias_bomb(draw) -> Doc:
    levels = draw(st.integers(2, 12))
    fan = draw(st.integers(2, 12))
    lines = [f'a0: &a0 [{", ".join(["lol"] * fan)}]']
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * fan)}]")
    key = draw(st.sampled_from(["name", "vehicles", "grid", "tests", "runs", "K", "zz"]))
    lines.append(f"{key}: *a{levels - 1}")
    if draw(st.booleans()):   # the whole bomb inside one list under a key
        items = [f"&b0 [{', '.join(['lol'] * fan)}]"]
        items += [f"&b{i} [{', '.join([f'*b{i - 1}'] * fan)}]" for i in range(1, levels)]
        lines = [f"{key}: [{', '.join(items)}]"]
    return Doc("bytes", ("\n".join(lines) + "\n").encode(), f"alias_bomb:{fan}^{levels}")


TAGS = ["!!python/object:os.system x", "!!python/object/apply:os.system ['true']", "!!python/name:os.system",
        "!!python/module:os", "!!python/tuple [1, 2]", "!!python/object/new:int [1]", "!!binary aGVsbG8=",
        "!!set {a, b}", "!!omap [a: 1, b: 2]", "!!pairs [a: 1]", "!!timestamp 2001-12-14", "2001-12-14t21:59:43Z",
        "!foo bar", "!<tag:example.com,2000:x> 1", "!!str 1", "!!int x", "!!int 0b2", "!!float abc",
        "!!bool maybe", "!!bool 2", "!!null x", "!!map [1, 2]", "!!seq {a: 1}", "!!merge x", "{<<: 5}",
        "{<<: [1, 2]}", "{<<: *undefined}", "*undefined", "&a 1", "!!int " + "9" * 5000,
        "0x" + "f" * 5000, "!!float " + "9" * 400, "[&a 1, &a 2]", "? [1, 2]\n: 3", "{[1]: 2}", "{{a: 1}: 2}",
        "!!python/str x", "!!python/bytes eA==", "!!python/complex 1+2j", "!!python/unicode x", "%YAML 1.1\n--- 1",
        "%TAG ! tag:example.com,2000:\n--- !x 1", "%FOO bar\n--- 1", "&a [*a]", "&a {x: *a}"]


@st.composite
def tagged(draw) -> Doc:
    tag = draw(st.sampled_from(TAGS))
    where = draw(st.sampled_from(["root", "name", "value", "list"]))
    if where == "root" or tag.startswith("%"):
        text = tag
    elif where == "list":
        text = f"name: x\nvehicles: [{tag}]" if "\n" not in tag else tag
    else:
        key = "name" if where == "name" else draw(st.sampled_from(["seed", "fps", "width", "grid", "suite", "zz"]))
        text = f"{key}: {tag}" if "\n" not in tag else tag
    return Doc("bytes", text.encode(), f"tag:{tag[:30]}")


EDGE_TEXTS = [b"", b" ", b"\n\n\n", b"# only a comment\n", b"---\n", b"---\n---\n", b"a: 1\n---\nb: 2\n", b"...\n",
              b"null", b"~", b"[]", b"{}", b"42", b'"a string"', b"- 1\n- 2\n", b"true", b".nan", b"-.inf",
              b"NaN", b"Infinity", b"[NaN, Infinity, -Infinity]", b'{"a": 1, "a": 2}', b"\xef\xbb\xbf{}",
              b"{", b"}", b"[", b"]", b":", b"- - - -", b"? ? ?", b"a: b: c", b"\t", b"'", b'"', b"&", b"*",
              b"!", b"%", b"@", b"`", b"|\n x", b">\n x", b"a:\n\t- 1", b"\x00", b"\x1b[31mred", b"\x85",
              b"\xe2\x80\xa8", b"\xc0\x80", b"\xed\xa0\x80", b"1e999", b"-1e999", b"9" * 5000, b"0." + b"0" * 5000 + b"1",
              b'{"x": ' + b"9" * 5000 + b"}", b'"\\ud800"', b'"\\u0000"', b"[1,]", b"[,1]", b"{'a': 1}",
              b"// comment\n{}", b"{} {}", b"{}\x00"]


@st.composite
def oversized(draw, limit: int, fmt: str) -> Doc:
    """A file beyond ``limit``: real content (comments, a long string, a long list) or a sparse file."""
    size = draw(st.sampled_from([limit + 1, limit + 4096, 2 * limit, 10 * limit]))
    kind = draw(st.sampled_from(["sparse", "comment", "string", "list"] if fmt == "yaml" else ["sparse", "string",
                                                                                               "list"]))
    if kind == "sparse" or size > 4 * MAX_CONFIG_BYTES:
        return Doc("sparse", b"", f"size={size}")
    if kind == "comment":
        data = b"name: big\n" + (b"# " + b"x" * 78 + b"\n") * (size // 80 + 1)
    elif kind == "string":
        data = b'{"name": "' + b"x" * size + b'"}'
    else:
        data = b"[" + b"1," * (size // 2) + b"1]"
    return Doc("bytes", data, f"oversized:{kind}:{len(data)}")


def fs_oddities() -> st.SearchStrategy:
    return st.sampled_from(FS_KINDS).map(lambda k: Doc(k, b"", k))


# ------------------------------------------------------------- JSON, invalid
#: Values that are no JSON in any place (Python's ``json`` reads NaN, Infinity and 1e999, so those are not here):
#: Python and JavaScript literals, other number syntaxes, an integer beyond ``json``'s 4,300 digits, broken
#: strings and containers, comments.
NOT_JSON = ["nan", "inf", "-inf", "None", "True", "False", "undefined", "'x'", "0x1F", "+1", "01", ".5", "1.",
            "1e", "--1", "9" * 5000, '"unterminated', '"tab\there"', '"line\nbreak"', '"bad \\x escape"', "x",
            "[1,]", '{"a": 1,}', "{'a': 1}", "{a: 1}", "[1 2]", '{"a" 1}', "/* c */ 1", "// c\n1", "[", "}"]
_HOLE = "\x00not-json\x00"     # a placeholder string, replaced by a NOT_JSON token once serialised


def _put(doc: Any, path: tuple, value: Any) -> Any:
    """``doc`` with the value at ``path`` replaced (the root when ``path`` is empty)."""
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


#: A break of a reader's schema: value -> strategy of values the reader refuses.
Break = Callable[[Any], st.SearchStrategy]


@st.composite
def broken_json(draw, values: st.SearchStrategy, breaks: tuple[Break, ...]) -> Doc:
    """A value of ``values`` made invalid by construction, as JSON: one of ``breaks`` of the reader's schema
    (none for a reader that takes any JSON), one value replaced by a token that is no JSON
    (:data:`NOT_JSON`), or one value nested deeper than ``MAX_DEPTH``."""
    value = copy.deepcopy(draw(values))
    how = draw(st.sampled_from(["not_json", "deep"] + ["schema"] * bool(breaks)))
    indent = draw(st.sampled_from([None, 2]))
    if how == "schema":
        return Doc("bytes", to_json(draw(draw(st.sampled_from(breaks))(value)), indent), "json:schema")
    path = draw(st.sampled_from(_slots(value)))
    if how == "deep":
        return Doc("bytes", to_json(_put(value, path, deep_list(draw(st.integers(MAX_DEPTH + 1, 200)))), indent),
                   "json:deep")
    token = draw(st.sampled_from(NOT_JSON))
    text = to_json(_put(value, path, _HOLE), indent).replace(json.dumps(_HOLE).encode(), token.encode(), 1)
    return Doc("bytes", text, "json:not_json")


def _is_json(text: bytes) -> bool:
    """Whether ``text`` is JSON as the readers take it (UTF-8, one leading BOM dropped, no NUL)."""
    try:
        decoded = text.decode("utf-8").removeprefix("\ufeff")
        json.loads(decoded)
    except ValueError:
        return False
    return "\x00" not in decoded


# ---------------------------------------------------------------------- readers
def _keys(base: dict) -> list[str]:
    return sorted({str(k) for p in _slots(base) for k in p if isinstance(k, str)})


def plausible_json(base: dict) -> st.SearchStrategy:
    """Documents that a lenient JSON reader may well accept: mutations of ``base`` (wrong types, missing and
    extra keys, NaN, ...) as they are, the edge texts that are JSON, file-system oddities."""
    return st.one_of(serialised(mutated(base, _keys(base)), "json"), serialised(mutated(base, _keys(base)), "json"),
                     st.sampled_from([t for t in EDGE_TEXTS if _is_json(t)]).map(lambda b: Doc("bytes", b, "edge")),
                     fs_oddities())


def documents(base: dict, fmt: str, limit: int = MAX_CONFIG_BYTES, valid_text: bytes | None = None,
              with_fs: bool = True, breaks: tuple[Break, ...] | None = None) -> st.SearchStrategy:
    """Malformed documents for a reader whose valid documents look like ``base`` (``fmt`` yaml or json).

    ``breaks`` (JSON only), for a reader that accepts most JSON: the breaks of its schema (:data:`Break`; an
    empty tuple when it takes any JSON value). Every branch then yields an invalid document by construction:
    mutated and arbitrary values through :func:`broken_json`, the ``strict_json`` corruptions, only the edge
    texts that are no JSON.
    """
    keys = _keys(base)
    valid = valid_text if valid_text is not None else (to_yaml(base, None) if fmt == "yaml" else to_json(base, 2))
    if breaks is None:
        values = lambda v: serialised(v, fmt)   # noqa: E731
        edge = EDGE_TEXTS
    else:
        values = lambda v: broken_json(v, breaks)   # noqa: E731
        edge = [t for t in EDGE_TEXTS if not _is_json(t)]
    branches = [
        values(mutated(base, keys)), values(mutated(base, keys)),
        values(mutated(base, keys)), values(mutated(base, keys)),
        values(json_values(keys)),
        corrupted(valid, strict_json=breaks is not None), corrupted(valid, strict_json=breaks is not None),
        deep_nesting(fmt),
        binary(),
        st.sampled_from(edge).map(lambda b: Doc("bytes", b, "edge")),
        oversized(limit, fmt),
    ]
    if fmt == "yaml":
        branches += [alias_bomb(), tagged(), tagged()]
    if with_fs:
        branches.append(fs_oddities())
    return st.one_of(*branches)
