"""Reading the project's YAML files (rig, scene, world) with one-line errors.

The reader validates before it trusts: the file must be a regular file of bounded
size, and the YAML is composed with a loader that

* builds only plain data (PyYAML's safe constructors: no Python tags ever run);
* refuses aliases (``*name``), so a few hundred bytes cannot expand into gigabytes;
* refuses nesting deeper than ``MAX_DEPTH`` (PyYAML composes recursively: a deep file
  would otherwise end in RecursionError) and more than ``MAX_NODES`` nodes;
* refuses duplicate keys in a mapping (PyYAML silently keeps the last one).

Messages that echo a value go through :func:`brief`, a repr cut to a few dozen
characters, so no input can make an error message large.
"""

from __future__ import annotations

import math
import stat
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.events import AliasEvent, MappingStartEvent, SequenceStartEvent

from slitcli.errors import SlitcliError

MAX_BYTES = 2 * 1024 * 1024
"""Largest YAML file read, bytes. A rig is about 2 kB, a scene with 10,000 poses 0.4 MB.

PyYAML's safe loader is pure Python (tens of microseconds a value): the byte and node
bounds keep the worst file to a few seconds."""
MAX_DEPTH = 32
"""Deepest nesting of sequences and mappings accepted (slitcli's files use at most 5)."""
MAX_NODES = 60_000
"""Most YAML nodes (scalars, sequences, mappings) in one file."""


class _Refused(yaml.YAMLError):
    """A structural limit of the bounded loader, with the line it was found at."""

    def __init__(self, problem: str, fix: str, mark: Any) -> None:
        super().__init__(problem)
        self.problem = problem
        self.fix = fix
        self.problem_mark = mark


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader without aliases, with bounded depth and node count, and unique keys."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(AliasEvent):
            event = self.peek_event()
            raise _Refused("uses a YAML alias (*name)", "write the value out in full; slitcli "
                           "does not expand aliases", event.start_mark)
        self._nodes += 1
        if self._nodes > MAX_NODES:
            raise _Refused(f"has more than {MAX_NODES} values", "give a smaller file",
                           self.peek_event().start_mark)
        nested = self.check_event(SequenceStartEvent, MappingStartEvent)
        if nested:
            self._depth += 1
            if self._depth > MAX_DEPTH:
                raise _Refused(f"nests deeper than {MAX_DEPTH} levels",
                               "flatten the file (slitcli's files nest at most 5 levels)",
                               self.peek_event().start_mark)
        try:
            return Composer.compose_node(self, parent, index)
        finally:
            if nested:
                self._depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                key = (key_node.tag, key_node.value)
                if key in seen:
                    raise _Refused(f"repeats the key {brief(key_node.value)}",
                                   "give every key once", key_node.start_mark)
                seen.add(key)
        return super().construct_mapping(node, deep=deep)



def brief(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to at most ``limit`` characters (never raises, never large).

    Huge integers are described by their digit count: ``repr`` of an int past 4,300
    digits raises in Python >= 3.11, and a cut repr of a number would mislead.
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"<integer of about {int(value.bit_length() * 0.30103) + 1} digits>"
    if isinstance(value, list | tuple | dict) and len(value) > 16:
        kind = type(value).__name__
        return f"<{kind} of {len(value)} items>"
    try:
        text = repr(value)
    except (ValueError, RecursionError, MemoryError):
        return f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def finite_float(value: Any) -> float | None:
    """``value`` as a finite float, or None if it is not a finite real number.

    Booleans are not numbers here (YAML's ``true`` is not 1), and integers too large for
    a float (``10**400``) are refused rather than raising OverflowError.
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        f = float(value)
    except OverflowError:
        return None
    return f if math.isfinite(f) else None


def load_yaml_text(text: str, source: str) -> Any:
    """Parse YAML text with the bounded loader; errors are one-line SlitcliErrors."""
    try:
        loader = _BoundedLoader(text)
        try:
            return loader.get_single_data()
        finally:
            loader.dispose()
    except _Refused as e:
        mark = e.problem_mark
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise SlitcliError(f"{source}: {e.problem}{where}; {e.fix}") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise SlitcliError(f"{source}: not valid YAML{where}; fix the syntax") from None
    except RecursionError:  # belt and braces: the depth bound stops this first
        raise SlitcliError(f"{source}: nests too deeply; flatten the file") from None


def read_text_bounded(path: str | Path, *, kind: str, missing_hint: str,
                      max_bytes: int = MAX_BYTES) -> str:
    """The text of a regular file of at most ``max_bytes``, or a one-line SlitcliError."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        if p.is_symlink():
            raise SlitcliError(f"{p}: {kind} is a symbolic link to a missing file; fix the "
                               "link or give the file itself") from None
        raise SlitcliError(f"{p}: {kind} not found; {missing_hint}") from None
    except OSError as e:
        raise SlitcliError(f"{p}: cannot read the {kind} ({e.strerror or e.__class__.__name__}); "
                           "check the path and permissions") from None
    if not stat.S_ISREG(st.st_mode):
        raise SlitcliError(f"{p}: {kind} is not a regular file; give the path of a YAML file")
    if st.st_size > max_bytes:
        raise SlitcliError(f"{p}: {kind} is {st.st_size} bytes, more than the "
                           f"{max_bytes} this slitcli reads; check that this is the right file")
    try:
        with p.open("rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as e:
        raise SlitcliError(f"{p}: cannot read the {kind} ({e.strerror or e.__class__.__name__}); "
                           "check the path and permissions") from None
    if len(data) > max_bytes:
        raise SlitcliError(f"{p}: {kind} is more than {max_bytes} bytes; check that this is "
                           "the right file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SlitcliError(f"{p}: {kind} is not UTF-8 text (byte {e.start}); save it as "
                           "UTF-8") from None


def read_yaml(path: str | Path, *, kind: str, missing_hint: str) -> Any:
    """Parse a YAML file; a missing, unreadable, oversized or malformed file is a SlitcliError.

    Parameters
    ----------
    path : path
    kind : str
        What the file is, for messages ("rig file", "scene file"...).
    missing_hint : str
        The fix to suggest when the file does not exist.
    """
    p = Path(path)
    text = read_text_bounded(p, kind=kind, missing_hint=missing_hint)
    return load_yaml_text(text, str(p))
