"""Results pages' report blocks: :func:`update_pages` reruns each ``<!-- report: ... -->`` block of a page and
replaces its body with the command's output, or (``check``) names each block that is out of date."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
import sys
from pathlib import Path

from agrl.report.columns import ReportError
from agrl.report.commands import _parser, run_command

BLOCK_START = re.compile(r"^<!-- report: (?P<command>.*?) -->\s*$")
BLOCK_END = "<!-- /report -->"
IMAGE_LINK = re.compile(r"!\[[^\]]*\]\((?P<path>[^)\s]+)\)")


def page_files(targets: list[str]) -> list[Path]:
    """The markdown files ``targets`` name (a folder: its ``*.md``, not below), sorted within each folder."""
    files = []
    for target in targets:
        path = Path(target)
        if path.is_dir():
            files += sorted(path.glob("*.md"))
        elif path.is_file():
            files.append(path)
        else:
            raise ReportError(f"{target}: no such file or folder; allowed: markdown pages or folders of them")
    return files


def run_block(command: str, draw: bool) -> tuple[int, str, str]:
    """Run ``python -m agrl.report <command>`` in this process: (exit code, standard output, standard error)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            arguments = shlex.split(command)
            if arguments and arguments[0] == "pages":
                raise ReportError("pages: a block cannot run pages")
            parser = _parser()
            code = run_command(parser.parse_args(arguments), parser, draw)
        except SystemExit as exited:  # argparse's errors
            code = exited.code if isinstance(exited.code, int) else 2
        except (ReportError, ValueError) as error:
            print(f"agrl.report: error: {error}", file=sys.stderr)
            code = 2
    return code, out.getvalue(), err.getvalue()


def update_pages(files: list[Path], check: bool) -> tuple[list[str], list[str]]:
    """Rerun every report block of ``files``; write the changed pages unless ``check``. Returns (one line per
    out-of-date block, one line per failed block), each naming the file and line."""
    stale, failed = [], []
    for path in files:
        lines = path.read_text(encoding="utf-8").split("\n")
        result: list[str] = []
        index = 0
        while index < len(lines):
            line = lines[index]
            result.append(line)
            match = BLOCK_START.match(line)
            index += 1
            if match is None:
                continue
            start = index
            end = next((number for number in range(start, len(lines)) if lines[number].strip() == BLOCK_END), None)
            where = f"{path}:{start}"
            if end is None:
                failed.append(f"{where}: report block without its closing {BLOCK_END}")
                continue
            body = lines[start:end]
            code, output, errors = run_block(match["command"], draw=not check)
            if code != 0:
                message = (errors.strip().splitlines() or [f"exit code {code}"])[-1]
                failed.append(f"{where}: report block `{match['command']}` failed: {message}")
                result += body
            else:
                new_body = output.rstrip("\n").split("\n")
                missing = [link["path"] for link in IMAGE_LINK.finditer(output)
                           if not (path.parent / link["path"]).is_file()]
                if new_body != body or missing:
                    what = f"figures missing: {', '.join(missing)}" if new_body == body else "text differs"
                    stale.append(f"{where}: report block `{match['command']}` is out of date ({what})")
                result += new_body
            result.append(lines[end])
            index = end + 1
        if not check:
            text = "\n".join(result)
            if text != path.read_text(encoding="utf-8"):
                path.write_text(text, encoding="utf-8")
    return stale, failed
