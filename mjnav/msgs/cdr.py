"""Compiled little-endian CDR encoders and decoders, one pair per message type, generated from the typestore.

rosbags generates one function per message type that calls the function of each nested type and unpacks every
primitive field with its own ``struct`` call. On the bus that cost is paid per message, in a process that was
sleeping a moment before, so the amount of Python executed shows up directly in the latency. The functions
generated here produce exactly rosbags' bytes and objects (``byte`` unsigned, as :mod:`mjnav.msgs.codec` presents
rosbags' too) with less of it:

* nested messages are inlined, so a LaserScan is one function, not three;
* consecutive primitive fields are packed or unpacked by one ``struct.Struct`` whose format carries the CDR
  alignment padding, whenever that padding is known when the code is generated (alignment is tracked statically
  from the last variable-length field; only after strings and sequences is it computed at run time);
* primitive arrays and sequences are ``numpy.frombuffer`` views on decode and ``ndarray.tobytes`` on encode.

Alignment follows CDR as rosbags implements it: each primitive is aligned to its size relative to the first byte
after the 4-byte encapsulation header, a sequence count to 4, the elements of a non-empty primitive sequence to
their size; there is no padding at the end of a nested message.

These are fast paths, not a second definition of the format. :func:`mjnav.msgs.codec.encoder` and
:func:`~mjnav.msgs.codec.decoder` fall back to rosbags for whatever a compiled function does not take: big-endian
payloads, malformed payloads (rosbags then produces the error), message objects holding something other than
exactly-typed values (e.g. a list or a float64 array where a float32 sequence is declared), and types with
``wstring`` or ``float128`` fields (no compiled functions at all). Tests compare both paths byte for byte and
object for object on random messages of every type in the typestore.
"""

from __future__ import annotations

import keyword
import struct
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

#: struct format character of each primitive. ``byte`` (the IDL ``octet``) and ``char`` are unsigned, as in ROS 2;
#: rosbags packs ``byte`` signed, and :mod:`mjnav.msgs.codec` converts on its rosbags path.
_FORMAT = {
    "bool": "?",
    "byte": "B",
    "char": "B",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
#: numpy dtype of primitive arrays and sequences (as rosbags decodes them, except ``byte``: uint8, not int8).
_DTYPE = {
    "bool": np.dtype(np.bool_),
    "byte": np.dtype(np.uint8),
    "char": np.dtype(np.uint8),
    "int8": np.dtype(np.int8),
    "uint8": np.dtype(np.uint8),
    "int16": np.dtype(np.int16),
    "uint16": np.dtype(np.uint16),
    "int32": np.dtype(np.int32),
    "uint32": np.dtype(np.uint32),
    "int64": np.dtype(np.int64),
    "uint64": np.dtype(np.uint64),
    "float32": np.dtype(np.float32),
    "float64": np.dtype(np.float64),
}
_SIZE = {name: struct.calcsize("<" + fmt) for name, fmt in _FORMAT.items()}


class Unsupported(Exception):
    """The type has a field the generator does not handle; rosbags serves it."""


class Fallback(Exception):
    """Raised inside a compiled function: this payload or object is left to rosbags."""


@dataclass(frozen=True)
class CompiledCodec:
    """The generated pair for one type. ``decode`` takes the whole payload; the caller has checked that its
    4-byte encapsulation header says little-endian CDR."""

    typename: str
    encode: Callable[[Any], bytes]
    decode: Callable[[bytes | memoryview], Any]
    source: str


def attribute_name(name: str) -> str:
    """Python attribute name of a field (rosbags appends ``_`` to keywords)."""
    return f"{name}_" if keyword.iskeyword(name) else name


def _aligned(pos: str, a: int) -> str:
    """Expression rounding payload index ``pos`` up so that ``pos - 4`` is a multiple of ``a``."""
    if a <= 4:  # the header is 4 bytes, so the index and the CDR offset are aligned alike
        return f"({pos} + {a - 1}) & -{a}"
    return f"(({pos} + {a - 5}) & -{a}) + 4"


def _alignment_of(offset: int, known: int) -> int:
    """Largest power of two <= 8 that divides both ``known`` and ``offset``."""
    a = known
    while a > 1 and offset % a:
        a //= 2
    return a


class _Emitter:
    """Shared bookkeeping: the generated function body and the namespace of the generated module."""

    def __init__(self, store: Typestore, namespace: dict[str, Any]) -> None:
        self.store = store
        self.ns = namespace
        self.lines: list[str] = []
        self._n = 0

    def name(self, prefix: str) -> str:
        self._n += 1
        return f"{prefix}{self._n}"

    def const(self, prefix: str, value: Any) -> str:
        """Name of ``value`` in the generated module's namespace (shared by all functions of one type)."""
        for k, v in self.ns.items():
            if v is value and k.startswith(prefix):
                return k
        key = f"{prefix}{len(self.ns)}"
        self.ns[key] = value
        return key

    def emit(self, line: str) -> None:
        self.lines.append("    " + line)

    def fields(self, typename: str) -> list[tuple[str, Any]]:
        return list(self.store.fielddefs[typename][1])

    def element_function(self, typename: str, kind: str, build: Callable[[str], None]) -> str:
        """Name of the generated per-element function for messages in arrays/sequences (generated once)."""
        key = f"_{kind}_{typename.replace('/', '_')}"
        if key not in self.ns:
            self.ns[key] = None  # reserve against recursion
            build(key)
        return key


class _DecodeGen(_Emitter):
    """Generates ``def NAME(d, pos) -> (obj, pos)`` or the top-level ``def decode(d) -> obj``.

    ``d`` is the whole payload and ``pos`` an index into it, so CDR's alignment, relative to the first byte after
    the 4-byte header, is computed on ``pos - 4`` (see :func:`_aligned`).
    """

    def __init__(self, store: Typestore, namespace: dict[str, Any]) -> None:
        super().__init__(store, namespace)
        self.known = 8  # guaranteed alignment of the run-time ``pos``
        self.off = 0  # static offset from ``pos``
        self.run_fmt = ""
        self.run_vars: list[str] = []
        self.run_start = 0
        self.run_end = 0

    # --- position bookkeeping
    def flush(self) -> None:
        if not self.run_vars:
            return
        s = self.const("_S", struct.Struct("<" + self.run_fmt))
        targets = ", ".join(self.run_vars) + ("," if len(self.run_vars) == 1 else "")
        at = f"pos + {self.run_start}" if self.run_start else "pos"
        self.emit(f"{targets} = {s}.unpack_from(d, {at})")
        self.run_fmt, self.run_vars = "", []

    def align(self, a: int) -> None:
        """Make ``pos + off`` aligned to ``a`` (statically when the known alignment allows)."""
        if a <= self.known:
            self.off += -self.off % a
            return
        self.flush()
        self.emit(f"pos = {_aligned(f'pos + {self.off}' if self.off else 'pos', a)}")
        self.off, self.known = 0, a

    def sync(self) -> None:
        """Fold the static offset into ``pos`` (before anything that advances ``pos`` at run time)."""
        self.flush()
        if self.off:
            self.emit(f"pos += {self.off}")
            self.known = _alignment_of(self.off, self.known)
            self.off = 0

    # --- fields
    def primitive(self, base: str) -> str:
        size = _SIZE[base]
        self.align(size)
        var = self.name("v")
        if not self.run_vars:
            self.run_start = self.run_end = self.off
        self.run_fmt += f"{self.off - self.run_end}x" if self.off > self.run_end else ""
        self.run_fmt += _FORMAT[base]
        self.run_vars.append(var)
        self.off += size
        self.run_end = self.off
        return var

    def string(self) -> str:
        n = self.primitive("uint32")  # the length (with the terminating NUL) joins the pending run
        self.sync()
        var = self.name("v")
        self.emit(f"if {n} < 1 or pos + {n} > len(d) or d[pos + {n} - 1]:")
        self.emit("    raise _Fallback")
        self.emit(f"{var} = str(d[pos : pos + {n} - 1], 'utf-8')")
        self.emit(f"pos += {n}")
        self.known = 1
        return var

    def count(self, minimum: int) -> str:
        """Read a sequence count (joining the pending run), check it fits the remaining bytes; returns its name."""
        n = self.primitive("uint32")
        self.sync()
        self.emit(f"if pos + {n} * {minimum} > len(d):")
        self.emit("    raise _Fallback")
        return n

    def array(self, base: str, length: int) -> str:
        size = _SIZE[base]
        self.align(size)
        self.flush()
        var = self.name("v")
        dt = self.const("_D", _DTYPE[base])
        self.emit(f"{var} = _frombuffer(d, {dt}, {length}, pos + {self.off})")
        self.off += size * length
        return var

    def sequence(self, base: str) -> str:
        size = _SIZE[base]
        n = self.count(size)
        var = self.name("v")
        if size > 4:
            self.emit(f"if {n}:")
            self.emit(f"    pos = {_aligned('pos', size)}")
        dt = self.const("_D", _DTYPE[base])
        self.emit(f"{var} = _frombuffer(d, {dt}, {n}, pos)")
        self.emit(f"pos += {n} * {size}")
        self.known = min(size, 4)
        return var

    def loop(self, length: int | None, minimum: int, body: list[str]) -> str:
        """A list read element by element: ``length`` of them (fixed array) or a sequence count (elements of at
        least ``minimum`` bytes); ``body`` reads one element into ``o`` and leaves ``pos`` after it."""
        if length is None:
            n = self.count(minimum)
        else:
            n = str(length)
            self.sync()
        var = self.name("v")
        self.emit(f"{var} = []")
        self.emit(f"for _ in range({n}):")
        for line in [*body, f"{var}.append(o)"]:
            self.emit("    " + line)
        self.known = 1
        return var

    def strings(self, length: int | None) -> str:
        return self.loop(
            length,
            5,
            [
                "pos = (pos + 3) & -4",
                "k = _u32(d, pos)[0]",
                "if k < 1 or pos + 4 + k > len(d) or d[pos + 3 + k]:",
                "    raise _Fallback",
                "o = str(d[pos + 4 : pos + 3 + k], 'utf-8')",
                "pos += 4 + k",
            ],
        )

    def messages(self, typename: str, length: int | None) -> str:
        func = self.element_function(typename, "dec", lambda key: _build_decoder(self.store, self.ns, typename, key))
        return self.loop(length, 1, [f"o, pos = {func}(d, pos)"])

    def message(self, typename: str) -> str:
        """Inline the fields of ``typename``; returns the expression constructing it."""
        args = [self.field(desc) for _, desc in self.fields(typename)]
        cls = self.const("_C", self.store.types[typename])
        return f"{cls}({', '.join(args)})"

    def field(self, desc: Any) -> str:
        nodetype, sub = desc
        if nodetype == Nodetype.NAME:
            return self.message(sub)
        if nodetype == Nodetype.BASE:
            base = sub[0]
            if base == "string":
                return self.string()
            if base not in _FORMAT:
                raise Unsupported(base)
            return self.primitive(base)
        (subtype, subdesc), length = sub
        fixed = length if nodetype == Nodetype.ARRAY else None
        if subtype == Nodetype.NAME:
            return self.messages(subdesc, fixed)
        base = subdesc[0]
        if base == "string":
            return self.strings(fixed)
        if base not in _FORMAT:
            raise Unsupported(base)
        return self.array(base, fixed) if fixed is not None else self.sequence(base)


def _build_decoder(store: Typestore, ns: dict[str, Any], typename: str, key: str) -> None:
    """Generate the element decoder ``key(d, pos) -> (obj, pos)`` into ``ns``."""
    gen = _DecodeGen(store, ns)
    gen.known = 1  # called at any position
    expr = gen.message(typename)
    gen.sync()
    _define(ns, f"def {key}(d, pos):", gen.lines, f"return {expr}, pos")


class _EncodeGen(_Emitter):
    """Generates ``def NAME(out, m)`` appending to a bytearray that starts with the 4-byte header."""

    def __init__(self, store: Typestore, namespace: dict[str, Any]) -> None:
        super().__init__(store, namespace)
        self.known = 8  # guaranteed alignment of len(out) - 4 at the start of the pending run
        self.off = 0  # bytes in the pending run
        self.run_fmt = ""
        self.run_exprs: list[str] = []

    def flush(self) -> None:
        if self.run_exprs:
            s = self.const("_S", struct.Struct("<" + self.run_fmt))
            self.emit(f"out += {s}.pack({', '.join(self.run_exprs)})")
        elif self.off:
            self.emit(f"out += _Z[:{self.off}]")
        self.known = _alignment_of(self.off, self.known)
        self.run_fmt, self.run_exprs, self.off = "", [], 0

    def align(self, a: int) -> None:
        if a <= self.known:
            pad = -self.off % a
            self.run_fmt += f"{pad}x" if pad else ""
            self.off += pad
            return
        self.flush()
        if a > self.known:
            self.emit(f"out += _Z[: (4 - len(out)) % {a}]")
            self.known = a

    def primitive(self, base: str, expr: str) -> None:
        size = _SIZE[base]
        self.align(size)
        self.run_fmt += _FORMAT[base]
        self.run_exprs.append(expr)
        self.off += size

    def string(self, expr: str) -> None:
        var = self.name("b")
        self.emit(f"{var} = {expr}.encode()")
        self.primitive("uint32", f"len({var}) + 1")  # the length joins the pending run
        self.flush()
        self.emit(f"out += {var}")
        self.emit("out += b'\\0'")
        self.known = 1

    def ndarray(self, base: str, expr: str, length: int | None) -> None:
        size = _SIZE[base]
        var = self.name("a")
        dt = self.const("_D", _DTYPE[base])
        self.emit(f"{var} = {expr}")
        check = f"type({var}) is not _ndarray or {var}.dtype != {dt} or {var}.ndim != 1"
        if length is not None:
            check += f" or len({var}) != {length}"
        self.emit(f"if {check}:")
        self.emit("    raise _Fallback")
        if length is None:
            self.primitive("uint32", f"len({var})")
            self.flush()
            if size > 4:
                self.emit(f"if len({var}):")
                self.emit(f"    out += _Z[: (4 - len(out)) % {size}]")
            self.emit(f"out += {var}.tobytes()")
            self.known = min(size, 4)
        else:
            self.align(size)
            self.flush()
            self.emit(f"out += {var}.tobytes()")
            self.known = _alignment_of(size * length, self.known)

    def loop(self, expr: str, length: int | None, body: list[str]) -> None:
        var = self.name("s")
        self.emit(f"{var} = {expr}")
        if length is None:
            self.primitive("uint32", f"len({var})")
            self.flush()
        else:
            self.flush()
            self.emit(f"if len({var}) != {length}:")
            self.emit("    raise _Fallback")
        self.emit(f"for e in {var}:")
        for line in body:
            self.emit("    " + line)
        self.known = 1

    def message(self, typename: str, expr: str) -> None:
        obj = self.name("o")
        self.emit(f"{obj} = {expr}")
        for fname, desc in self.fields(typename):
            self.field(desc, f"{obj}.{attribute_name(fname)}")

    def field(self, desc: Any, expr: str) -> None:
        nodetype, sub = desc
        if nodetype == Nodetype.NAME:
            self.message(sub, expr)
            return
        if nodetype == Nodetype.BASE:
            base = sub[0]
            if base == "string":
                self.string(expr)
            elif base in _FORMAT:
                self.primitive(base, expr)
            else:
                raise Unsupported(base)
            return
        (subtype, subdesc), length = sub
        fixed = length if nodetype == Nodetype.ARRAY else None
        if subtype == Nodetype.NAME:
            func = self.element_function(subdesc, "enc", lambda key: _build_encoder(self.store, self.ns, subdesc, key))
            self.loop(expr, fixed, [f"{func}(out, e)"])
            return
        base = subdesc[0]
        if base == "string":
            body = [
                "out += _Z[: (4 - len(out)) % 4]",
                "b = e.encode()",
                "out += _p32(len(b) + 1)",
                "out += b",
                "out += b'\\0'",
            ]
            self.loop(expr, fixed, body)
        elif base in _FORMAT:
            self.ndarray(base, expr, fixed)
        else:
            raise Unsupported(base)


def _build_encoder(store: Typestore, ns: dict[str, Any], typename: str, key: str) -> None:
    """Generate the element encoder ``key(out, m)`` into ``ns``."""
    gen = _EncodeGen(store, ns)
    gen.known = 1
    gen.message(typename, "m")
    gen.flush()
    _define(ns, f"def {key}(out, m):", gen.lines, "return None")


def _define(ns: dict[str, Any], head: str, body: list[str], tail: str) -> None:
    """Compile one generated function into ``ns`` (its source is kept for error reports and tests)."""
    source = "\n".join([head, *body, f"    {tail}", ""])
    exec(compile(source, f"<mjnav.msgs.cdr {head}>", "exec"), ns)
    ns.setdefault("__sources__", []).append(source)


@cache
def compiled(store: Typestore, typename: str) -> CompiledCodec | None:
    """The compiled codec of ``typename`` in ``store``, or None when the type has unsupported fields."""
    ns: dict[str, Any] = {
        "_u32": struct.Struct("<I").unpack_from,
        "_p32": struct.Struct("<I").pack,
        "_frombuffer": np.frombuffer,
        "_ndarray": np.ndarray,
        "_Z": bytes(8),
        "_Fallback": Fallback,
    }
    try:
        dec = _DecodeGen(store, ns)
        expr = dec.message(typename)
        dec.sync()
        dec.emit("if pos + 3 < len(d):")  # rosbags: at most 3 bytes of trailing padding
        dec.emit("    raise _Fallback")
        _define(ns, "def _decode(d):", ["    pos = 4", *dec.lines], f"return {expr}")
        enc = _EncodeGen(store, ns)
        enc.message(typename, "m")
        enc.flush()
        header = "    out = bytearray(b'\\x00\\x01\\x00\\x00')"  # little-endian CDR encapsulation
        _define(ns, "def _encode(m):", [header, *enc.lines], "return bytes(out)")
    except Unsupported:
        return None
    return CompiledCodec(typename, ns["_encode"], ns["_decode"], "\n".join(ns["__sources__"]))
