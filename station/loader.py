"""One scenario loader: a scenario file read once and returned as what it describes.

A file with ``[[passes]]`` is a block of passes (:class:`BlockScenario`), one with a
``[sar]`` table a SAR frame (:class:`station.sar_scenario.SarScenario`), any other a pass
(:class:`station.scenario.Scenario`). :func:`load_any` reads the TOML once, checks it
whole and returns the one that it is; :func:`load_scenario` (a pass), :func:`load_block`
and :func:`load_sar` refuse the other kinds in one line, naming what the file is.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from levels.options import ProcessingOptions, describe_section
from station.errors import ScenarioError
from station.sar_scenario import SarConfig, SarScenario, sar_scenario_from_dict
from station.scenario import (
    SECTIONS,
    Scenario,
    check_name,
    merge_tables,
    read_toml,
    scenario_from_dict,
)

__all__ = [
    "BLOCK_KEY",
    "SAR_KEY",
    "BlockScenario",
    "describe_keys",
    "load_any",
    "load_block",
    "load_sar",
    "load_scenario",
]

#: The key of a scenario file that makes it a block: an array of tables, one per pass.
BLOCK_KEY = "passes"
#: The table that makes a scenario a SAR frame's.
SAR_KEY = "sar"


@dataclass(frozen=True)
class BlockScenario:
    """A block of passes (``[[passes]]``): its name, each pass's scenario (each a run of
    one pass making what it can alone, :func:`levels.block.pass_levels`) and the block's
    own processing (level 2's adjustment, the pair's kinds, level 3)."""

    name: str
    passes: tuple[Scenario, ...]
    processing: ProcessingOptions
    source: str = ""
    source_sha256: str = ""

    def inputs(self) -> list[Path]:
        """The files the block reads: each pass's (the file itself once)."""
        seen: dict[Path, None] = {}
        for s in self.passes:
            seen.update(dict.fromkeys(s.inputs()))
        return list(seen)


def _what(data: dict[str, object]) -> str:
    if BLOCK_KEY in data:
        return "a block of several passes ([[passes]])"
    if SAR_KEY in data:
        return "a SAR frame ([sar])"
    return "one pass"


def load_any(path: str | Path) -> Scenario | BlockScenario | SarScenario:
    """Read a scenario file once and return the pass, block or SAR scenario it describes;
    :class:`ScenarioError` says what is wrong."""
    p = Path(path)
    data, raw = read_toml(p)
    return _of_table(data, raw, p)


def _of_table(
    data: dict[str, object], raw: bytes, p: Path
) -> Scenario | BlockScenario | SarScenario:
    if not data:  # every key has a default: an empty file would run a full 60 km scene
        raise ScenarioError(
            f"{p}: an empty scenario ({len(raw)} bytes, no key): say at least its name; "
            "scenarios/quickstart.toml is a small one to start from, scenarios/README.md "
            "says every key"
        )
    if BLOCK_KEY in data:
        return _block(data, raw, p)
    scn: Scenario | SarScenario
    if SAR_KEY in data:
        scn = sar_scenario_from_dict(data, p)
    else:
        scn = scenario_from_dict(data, p.resolve().parent)
    return dataclasses.replace(
        scn, source=str(p.resolve()), source_sha256=hashlib.sha256(raw).hexdigest()
    )


def _only(path: str | Path, want: type, what: str) -> Any:
    p = Path(path)
    data, raw = read_toml(p)
    if not isinstance(got := _of_table(data, raw, p), want):
        raise ScenarioError(f"{p} describes {_what(data)}, not {what}")
    return got


def load_scenario(path: str | Path) -> Scenario:
    """A pass's scenario file, read and checked (:func:`load_any`; a block's or a SAR
    frame's refused, naming what it is)."""
    return _only(path, Scenario, "one pass")


def load_block(path: str | Path) -> BlockScenario:
    """A block's scenario file (``[[passes]]``), read and checked."""
    return _only(path, BlockScenario, "a block of passes")


def load_sar(path: str | Path) -> SarScenario:
    """A SAR frame's scenario file (``[sar]``), read and checked."""
    return _only(path, SarScenario, "a SAR frame")


def _block(data: dict[str, Any], raw: bytes, p: Path) -> BlockScenario:
    """A block file's passes (module docstring of :mod:`station.run`): each
    ``[[passes]]`` table merged over the file's other tables (the world, the instrument,
    the errors…), its own ``name`` (``p1``, ``p2``… by default) naming the pass
    ``<block>_<name>``, its ``seed`` (default: the block's plus its rank) drawing its
    errors independently; each pass making the levels of one pass (its ``[processing]
    levels`` less what the block makes), its file's digest its own."""
    from levels.block import pass_levels

    data = dict(data)
    passes = data.pop(BLOCK_KEY)
    if not isinstance(passes, list) or len(passes) < 2:
        raise ScenarioError(f"{p}: [[{BLOCK_KEY}]] must be given twice or more (a block)")
    name = check_name(str(data.get("name", p.stem)))
    seed = int(data.get("seed", 0))
    block = scenario_from_dict(data, p.resolve().parent)  # the shared tables, checked
    scns = []
    for k, over in enumerate(passes):
        if not isinstance(over, dict):
            raise ScenarioError(f"{p}: [[{BLOCK_KEY}]] {k + 1} is not a table")
        over = dict(over)
        tag = check_name(str(over.pop("name", f"p{k + 1}")), f"[[{BLOCK_KEY}]] name")
        table = merge_tables(data, over)
        table["name"] = f"{name}_{tag}"
        if "seed" not in over:
            table["seed"] = seed + k + 1
        processing = dict(table.get("processing", {}))
        processing["levels"] = pass_levels(block.processing)
        processing["adjustment"] = "pass"
        table["processing"] = processing
        scn = scenario_from_dict(table, p.resolve().parent)
        digest = hashlib.sha256(raw + tag.encode()).hexdigest()  # the pass's own
        scns.append(dataclasses.replace(scn, source=str(p.resolve()), source_sha256=digest))
    if len({s.name for s in scns}) != len(scns):
        raise ScenarioError(f"{p}: two [[{BLOCK_KEY}]] named alike")
    return BlockScenario(
        name,
        tuple(scns),
        block.processing,
        source=str(p.resolve()),
        source_sha256=hashlib.sha256(raw).hexdigest(),
    )


def describe_keys() -> str:
    """Every key of every section, with its default (TOML units), range and meaning; then
    a block's ``[[passes]]`` and a SAR frame's ``[sar]``."""
    lines = [line for section, cls in SECTIONS.items() for line in describe_section(section, cls)]
    lines += [
        "[[passes]]  # a block of passes (twice or more, docs/blocks.md): each table merged "
        "over the file's other tables",
        "  name = 'p1'  # the pass, named <block name>_<name>; p1, p2… by default",
        "  seed = 0  # its errors' seed; default: the block's seed plus the pass's rank",
        "  # and any section above ([pass], [instrument], [gcps] …): the pass's own values",
    ]
    lines += describe_section("sar", SarConfig)
    lines.append("  # a SAR frame's file (docs/sar.md) takes [sar], [world] and [dem] only")
    return "\n".join(lines)
