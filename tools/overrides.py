"""``--set SECTION.KEY=VALUE`` of the tool scripts: scenario changes as a nested table."""

from __future__ import annotations

import json


def scenario_changes(items: list[str]) -> dict:
    """``["gcps.count=15", …]`` as ``{"gcps": {"count": 15}, …}`` (each value JSON)."""
    changes: dict = {}
    for item in items:
        key, value = item.split("=", 1)
        section, name = key.split(".", 1)
        changes.setdefault(section, {})[name] = json.loads(value)
    return changes
