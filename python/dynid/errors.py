"""The exceptions of dynid.

Every error carries the runtime's ``code`` (as the command line prints it, e.g.
``dynid::data::non_finite``) and a ``help`` line saying what to do.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional


class DynidError(Exception):
    """An error of dynid: a model, data or option it refuses, or a run that failed."""

    code: str = ""
    help: str = ""


class CompileError(DynidError, ValueError):
    """A model that does not compile.

    ``str(err)`` is the rendered diagnostic of every error in the source (file, line,
    column, the offending text and a help line); ``line`` and ``column`` (1-based) locate
    the first error, ``errors`` lists all of them as dicts (``code``, ``message``, ``help``,
    ``line``, ``column``).
    """

    rendered: str = ""
    line: Optional[int] = None
    column: Optional[int] = None
    errors: List[Dict[str, Any]] = []


class DataError(DynidError, ValueError):
    """Data that cannot be used, naming where the problem is.

    ``level`` is the 1-based position of the level in the list given, ``column`` the
    column's name and ``sample`` the 1-based sample number, where they apply (else None).
    """

    level: Optional[int] = None
    column: Optional[str] = None
    sample: Optional[int] = None
