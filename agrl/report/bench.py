"""The benchmarks' table: one line per measurement of ``make bench``'s JSON lines."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

#: others (timing repeats, calls per timing, load) say how, and stay in the JSON lines.
BENCH_SETTING_FIELDS = ("device", "trainer", "shape", "guide", "actions", "batch", "compiled", "compile_cache",
                        "cpu_path", "candidates", "z", "reset")
#: Fields shown as their own columns when a line has them: the comparisons a reader looks for.
BENCH_COMPARISONS = {"speedup_vs_reference": "× the reference", "collection_s": "collection s",
                     "update_s": "update s", "first_call_seconds": "first call s"}


def _bench_value(value: Any) -> str:
    if isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return f"{value:,.0f}" if abs(value) >= 1000 else format(value, ".4g")
    return "-" if value is None else str(value)


def _bench_setting(value: Any) -> str:
    return json.dumps(value) if isinstance(value, bool) else str(value)


def bench_table(paths: list[Path]) -> str:
    """One line per measurement in ``make bench``'s JSON lines (other lines, e.g. library logging, are skipped):
    its name, what was measured (:data:`BENCH_SETTING_FIELDS`), value, unit and :data:`BENCH_COMPARISONS`. The
    ``machine`` lines are left out: the page says which machine it was."""
    lines = ["| name | setting | value | unit | " + " | ".join(BENCH_COMPARISONS.values()) + " |",
             "|---|---|---:|---|" + "---:|" * len(BENCH_COMPARISONS)]
    for path in paths:
        for text in path.read_text(encoding="utf-8").splitlines():
            try:
                record = json.loads(text)
            except json.JSONDecodeError:
                continue
            if not isinstance(record, dict) or record.get("name") == "machine":
                continue
            setting = ", ".join(f"{key}={_bench_setting(record[key])}" for key in BENCH_SETTING_FIELDS
                                if key in record) or "-"
            comparisons = " | ".join(_bench_value(record.get(key)) for key in BENCH_COMPARISONS)
            lines.append(f"| {record.get('name', '-')} | {setting.replace('|', '/')} | "
                         f"{_bench_value(record.get('value'))} | {record.get('unit', '-')} | {comparisons} |")
    return "\n".join(lines)
