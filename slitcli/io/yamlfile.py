"""Reading the project's YAML files (rig, scene, world) with one-line errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from slitcli.errors import SlitcliError


def read_yaml(path: str | Path, *, kind: str, missing_hint: str) -> Any:
    """Parse a YAML file; a missing, unreadable or malformed file is a SlitcliError.

    Parameters
    ----------
    path : path
    kind : str
        What the file is, for messages ("rig file", "scene file"...).
    missing_hint : str
        The fix to suggest when the file does not exist.
    """
    p = Path(path)
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise SlitcliError(f"{p}: {kind} not found; {missing_hint}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SlitcliError(f"{p}: cannot read the {kind} ({e.__class__.__name__}); check the "
                           "path and permissions") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise SlitcliError(f"{p}: not valid YAML{where}; fix the syntax") from None
