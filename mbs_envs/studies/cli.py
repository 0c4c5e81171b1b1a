"""Argument types of the command lines: each refuses a bad value before any work, in argparse's own error format
(``error: argument --fps: ...``), since argparse reports the ``ArgumentTypeError`` of a type as that argument's.
"""

from __future__ import annotations

import argparse
import json
import pathlib
from typing import Any


def positive_int(text: str) -> int:
    """An integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}") from None
    if not (0.0 < value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def json_object(text: str) -> dict[str, Any]:
    """A JSON object (a dict of keyword arguments)."""
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        raise argparse.ArgumentTypeError(f"must be a JSON object, got {text!r} ({e.msg})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f'must be a JSON object ({{"name": value, ...}}), got {text!r}')
    return value


def out_folder(text: str) -> pathlib.Path:
    """A folder to write into: it may exist (as a folder) or not yet; an existing file is refused."""
    path = pathlib.Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"must be a folder, got the file {text!r}")
    return path
