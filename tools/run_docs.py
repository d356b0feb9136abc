"""Run every command example in README.md and docs/**/*.md and compare its output.

Docs that run cannot go stale: CI runs this check (tests/test_docs_run.py), and
``--update`` rewrites the shown outputs from what the commands print now. The convention
is written for authors in docs/contributing.md; in short:

- A ```console block holds commands, each on a line that starts with ``$ `` (a line ending
  in ``\\`` continues on the next), followed by the exact output it prints (stdout and stderr
  as a terminal shows them). A line ``...`` in an output stands for any number of lines.
- Every command of a page runs in order in one scratch directory of its own, which holds a
  copy of ``examples/``; a block whose info string has ``title="NAME"`` is written there as
  the file NAME first, so a page can show a file and then use it.
- An HTML comment right before a block (``<!-- docs-run: ... -->``) says how to run it:
  ``mask='REGEX'`` hides what varies (timings) in the expected and the actual output alike,
  ``needs=umockdev`` runs it only where umockdev and i2c-tools are installed (and under the
  pytest marker of the same name; ``needs=kernel`` where a guest engine is ready), ``fails`` expects its last command to exit non-zero,
  ``timeout=SECONDS`` allows longer than 120 s, and ``skip='REASON'`` does not run it (a
  root prompt ``# ``, a QEMU guest, hardware); ``sh``/``bash`` blocks must say ``skip``.
  Skipped ``bmg160-emu`` commands are still parsed by the real argument parser, every
  ``examples/...`` path a command names must exist, and a ``bmg160-emu ...`` quoted in
  the prose must name a real sub-command and real options.

Usage: ``python tools/run_docs.py [--update] [PAGE ...]`` (default: every page).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"^\s*<!--\s*docs-run:(.*?)-->\s*$")
FENCE = re.compile(r"^(\s*)(`{3,})\s*([\w+-]*)(.*)$")
TITLE = re.compile(r'title="([^"/\\]+)"')
RUN_LANGUAGES = {"console"}
LISTING_LANGUAGES = {"sh", "bash", "shell", "zsh"}  # commands without output: skip with reason
PROMPTS = ("$ ", "# ")
ELISION = "..."
DEFAULT_TIMEOUT_S = 120.0
# What a need asks of the machine: programs on PATH (and for umockdev its Python binding,
# probed as tests/test_umockdev_programs.py does); a need's name is also its pytest marker.
NEEDS = {
    "umockdev": ("umockdev-run", "i2cget", "i2ctransfer", "i2cdetect", "i2cset", "i2cdump"),
    "firmware": ("avr-gcc", "avr-objcopy", "simavr"),
    "kernel": ("modinfo", "i2cget"),  # and a ready guest engine (bmg160-emu kernel prepare)
}


class DocsError(Exception):
    """A block that breaks the convention: page, block and line, in one sentence."""


@dataclass
class Options:
    skip: str | None = None
    needs: list[str] = field(default_factory=list)
    masks: list[re.Pattern[str]] = field(default_factory=list)
    fails: bool = False
    timeout_s: float = DEFAULT_TIMEOUT_S


@dataclass
class Command:
    line: int  # 1-based page line of the prompt
    prompt: str
    text: str  # continuation lines joined, as bash reads them
    expected: list[str]
    output_start: int  # 0-based page line range of the shown output
    output_end: int


@dataclass
class Block:
    page: Path
    number: int  # 1-based among the page's fenced blocks
    line: int  # 1-based page line of the opening fence
    language: str
    indent: str
    body: list[str]
    options: Options
    title: str | None
    commands: list[Command] = field(default_factory=list)

    def where(self, line: int | None = None) -> str:
        at = f", line {line}" if line is not None else f" (line {self.line})"
        return f"{relative(self.page)}, block {self.number}{at}"


def relative(path: Path) -> str:
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return str(path)


def pages(root: Path = ROOT) -> list[Path]:
    """README.md and every page under docs/, in a stable order."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def parse_options(text: str, where: str) -> Options:
    options = Options()
    try:
        words = shlex.split(text)
    except ValueError as exc:
        raise DocsError(f"{where}: docs-run marker does not parse: {exc}") from None
    for word in words:
        key, _, value = word.partition("=")
        if key == "skip" and value:
            options.skip = value
        elif key == "needs" and value in NEEDS:
            options.needs.append(value)
        elif key == "mask" and value:
            try:
                options.masks.append(re.compile(value))
            except re.error as exc:
                raise DocsError(f"{where}: mask {value!r} is not a regular expression: {exc}") from None
        elif key == "fails" and not value:
            options.fails = True
        elif key == "timeout" and value.replace(".", "", 1).isdigit():
            options.timeout_s = float(value)
        else:
            raise DocsError(
                f"{where}: unknown docs-run option {word!r}; valid: skip='REASON', "
                f"needs={'|'.join(NEEDS)}, mask='REGEX', fails, timeout=SECONDS"
            )
    return options


def parse_page(page: Path) -> list[Block]:
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    pending: list[tuple[int, str]] = []  # docs-run markers waiting for their block
    index = 0
    while index < len(lines):
        line = lines[index]
        marker = MARKER.match(line)
        if marker:
            pending.append((index + 1, marker.group(1)))
            index += 1
            continue
        fence = FENCE.match(line)
        if not fence:
            if line.strip() and pending:
                raise DocsError(f"{relative(page)}, line {pending[0][0]}: a docs-run marker "
                                "must come right before a fenced block")
            index += 1
            continue
        indent, ticks, language, attributes = fence.groups()
        end = index + 1
        while end < len(lines) and not (lines[end].strip() == ticks
                                        and lines[end].startswith(indent)):
            end += 1
        if end == len(lines):
            raise DocsError(f"{relative(page)}, line {index + 1}: unclosed ``` block")
        number = len(blocks) + 1
        where = f"{relative(page)}, block {number} (line {index + 1})"
        options = Options()
        for _, text in pending:
            more = parse_options(text, where)
            options.skip = more.skip or options.skip
            options.needs += more.needs
            options.masks += more.masks
            options.fails = options.fails or more.fails
            if more.timeout_s != DEFAULT_TIMEOUT_S:
                options.timeout_s = more.timeout_s
        if pending and language not in RUN_LANGUAGES | LISTING_LANGUAGES:
            raise DocsError(f"{where}: docs-run markers apply to console and shell blocks only")
        pending = []
        title = TITLE.search(attributes)
        body = [raw[len(indent):] if raw.startswith(indent) else raw.lstrip()
                for raw in lines[index + 1:end]]
        block = Block(page, number, index + 1, language, indent, body, options,
                      title.group(1) if title else None)
        if language in RUN_LANGUAGES:
            block.commands = parse_console(block, index + 1)
        blocks.append(block)
        index = end + 1
    return blocks


def parse_console(block: Block, first: int) -> list[Command]:
    """The commands of a console block; ``first`` is the 0-based page line of its body."""
    commands: list[Command] = []
    row = 0
    # A root prompt ('# ') is a command only in a skipped block: elsewhere such a line is
    # output (a dump's header comment), since commands that need root are not run here.
    prompts = PROMPTS if block.options.skip is not None else ("$ ",)
    while row < len(block.body):
        line = block.body[row]
        if not line.startswith(prompts):
            if not commands:
                raise DocsError(f"{block.where(first + row + 1)}: a console block starts with "
                                "a '$ ' command line")
            commands[-1].expected.append(line.rstrip())
            commands[-1].output_end = first + row + 1
            row += 1
            continue
        prompt, text = line[:2], line[2:]
        start = row
        while text.endswith("\\") and row + 1 < len(block.body):
            row += 1
            text = text + "\n" + block.body[row]
        commands.append(Command(first + start + 1, prompt.strip(), text, [],
                                first + row + 1, first + row + 1))
        row += 1
    return commands


def environment(scratch: Path) -> dict[str, str]:
    """The same terminal for every run: this interpreter's bmg160-emu first on PATH, 80
    columns, UTC, no colour, no pytest options leaking in from the caller."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "COV_"))}
    env.update(
        PATH=f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}",
        COLUMNS="80", LINES="24", TERM="dumb", NO_COLOR="1", TZ="UTC", LC_ALL="C.UTF-8",
        PYTHONUNBUFFERED="1", PYTHONHASHSEED="0", PYTHONDONTWRITEBYTECODE="1", MPLBACKEND="Agg",
        TMPDIR=str(scratch),
    )
    return env


def masked(line: str, masks: list[re.Pattern[str]]) -> str:
    for mask in masks:
        line = mask.sub("<masked>", line)
    return line.rstrip()


def matches(expected: list[str], actual: list[str], masks: list[re.Pattern[str]]) -> bool:
    """Line by line after masking; an ``...`` line stands for any number of lines."""
    want = [masked(line, masks) for line in expected]
    got = [masked(line, masks) for line in actual]

    def fit(i: int, j: int) -> bool:
        if i == len(want):
            return j == len(got)
        if want[i].strip() == ELISION:
            return any(fit(i + 1, k) for k in range(j, len(got) + 1))
        return j < len(got) and want[i] == got[j] and fit(i + 1, j + 1)

    return fit(0, 0)


def regenerated(expected: list[str], actual: list[str], masks: list[re.Pattern[str]]) -> list[str]:
    """The output to show for ``actual``: the page's own lines where they still match
    (keeping masked timings as written), one ``...`` kept if the page had one."""
    if matches(expected, actual, masks):
        return expected
    if len(expected) == len(actual) and ELISION not in (line.strip() for line in expected):
        return [old if masked(old, masks) == masked(new, masks) else new
                for old, new in zip(expected, actual)]
    elisions = [i for i, line in enumerate(expected) if line.strip() == ELISION]
    if len(elisions) == 1:
        head, tail = elisions[0], len(expected) - elisions[0] - 1
        if len(actual) > head + tail:
            return actual[:head] + [expected[head]] + (actual[len(actual) - tail:] if tail else [])
    return actual


def difference(block: Block, command: Command, actual: list[str]) -> str:
    """Which page line differs, what it says and what the command printed."""
    want = [masked(line, block.options.masks) for line in command.expected]
    got = [masked(line, block.options.masks) for line in actual]
    first = next((i for i, (a, b) in enumerate(zip(want, got)) if a != b), min(len(want), len(got)))
    page_line = command.output_start + first + 1
    shown = command.expected[first] if first < len(command.expected) else "(end of output)"
    printed = actual[first] if first < len(actual) else "(end of output)"
    diff = "\n".join(difflib.unified_diff(command.expected, actual, "page", "command", lineterm="",
                                          n=2))
    lines = diff.splitlines()
    if len(lines) > 40:
        diff = "\n".join(lines[:40] + [f"... ({len(lines) - 40} more diff lines)"])
    return (f"{block.where(page_line)}: the output of `{command.text}` differs\n"
            f"  page:    {shown}\n  command: {printed}\n{diff}\n"
            f"  (python tools/run_docs.py --update {relative(block.page)} rewrites it)")


def umockdev_missing() -> str | None:
    from bmg160_emu.linux.umockdev import UMockdevUnavailable, load_umockdev, preload_available

    try:
        load_umockdev()
    except UMockdevUnavailable as exc:
        return str(exc)
    return None if preload_available() else "umockdev's preload library (libumockdev0)"


def unavailable(options: Options) -> list[str]:
    """What the block's needs ask for and this machine lacks."""
    missing = [program for need in options.needs for program in NEEDS[need]
               if shutil.which(program) is None]
    if "umockdev" in options.needs and not missing:
        missing += [reason for reason in [umockdev_missing()] if reason]
    if "kernel" in options.needs and not missing:
        from bmg160_emu.linux.guest.engine import default_engine

        if default_engine() is None:
            missing.append("a ready guest engine (bmg160-emu kernel prepare)")
    return missing


def check_listing(block: Block, command: str, line: int, scratch: Path | None = None) -> list[str]:
    """A command that is shown but not run: its bmg160-emu arguments still parse (in the
    page's scratch directory, where its earlier blocks' files are), and the examples/ files
    it names exist."""
    problems = []
    try:
        lexer = shlex.shlex(command, posix=True, punctuation_chars=True)
        lexer.whitespace_split = True
        lexer.commenters = "#"
        words = list(lexer)
    except ValueError as exc:
        return [f"{block.where(line)}: `{command}` does not parse as a shell line: {exc}"]
    for word in words:
        if word.startswith("examples/") and not (ROOT / word).exists():
            problems.append(f"{block.where(line)}: `{command}` names {word}, which does not exist")
    segments: list[list[str]] = [[]]
    for word in words:
        if word and set(word) <= set(";|&()<>"):
            segments.append([])
        else:
            segments[-1].append(word)
    for segment in segments:
        if not segment or segment[0] != "bmg160-emu" or any("$" in word for word in segment):
            continue
        from bmg160_emu.cli import build_parser

        errors = io.StringIO()
        try:
            with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.chdir(scratch or Path.cwd()):
                build_parser().parse_args(segment[1:])
        except SystemExit as exc:
            if exc.code:
                message = errors.getvalue().strip().splitlines()[-1:] or ["(no message)"]
                problems.append(f"{block.where(line)}: `{command}` is refused by the argument "
                                f"parser: {message[0]}")
    return problems


INLINE = re.compile(r"`bmg160-emu ([^`]+)`")


def _options_of(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string of ``parser`` and of its own sub-commands (firmware build ...)."""
    found: set[str] = set()
    for action in parser._actions:
        found.update(action.option_strings)
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found |= _options_of(sub)
    return found


def check_inline(page: Path, lines: list[str], fenced: set[int]) -> list[str]:
    """Commands quoted in the prose (```bmg160-emu trace --replay```) are fragments, not
    runnable, but their sub-command and every option they name must exist."""
    from bmg160_emu.cli import build_parser

    commands = next(a for a in build_parser()._actions
                    if isinstance(a, argparse._SubParsersAction)).choices
    problems = []
    for number, line in enumerate(lines, 1):
        if number in fenced:
            continue
        for match in INLINE.finditer(line):
            words = match.group(1).split()
            where = f"{relative(page)}, line {number}: `bmg160-emu {match.group(1)}`"
            name = words[0].rstrip(":")
            if name not in commands:
                if not words[0].endswith(":"):  # "bmg160-emu run: error ..." quotes a message
                    problems.append(f"{where} names no sub-command {words[0]!r}")
                continue
            known = _options_of(commands[name]) | {"--"}
            for word in words[1:]:
                option = word.strip("[]()|,.").split("=")[0]
                if option.startswith("--") and option not in known:
                    problems.append(f"{where}: {name} has no option {option}")
    return problems


@dataclass
class PageResult:
    page: Path
    ran: int = 0
    skipped: list[str] = field(default_factory=list)  # "block N (line L): reason"
    failures: list[str] = field(default_factory=list)
    updates: dict[int, list[str]] = field(default_factory=dict)  # output_start -> new lines
    spans: dict[int, int] = field(default_factory=dict)  # output_start -> output_end


def run_page(page: Path, *, markers: set[str] | None = None, update: bool = False) -> PageResult:
    """Run a page's blocks in one scratch directory. ``markers``: the needs whose blocks run
    (None: all that the machine can run); blocks of other needs are skipped."""
    result = PageResult(page)
    try:
        blocks = parse_page(page)
    except DocsError as exc:
        result.failures.append(str(exc))
        return result
    fenced = {block.line + offset for block in blocks for offset in range(len(block.body) + 2)}
    result.failures += check_inline(page, page.read_text(encoding="utf-8").splitlines(), fenced)
    with tempfile.TemporaryDirectory(prefix="bmg160-docs-") as name:
        scratch = Path(name)
        shutil.copytree(ROOT / "examples", scratch / "examples",
                        ignore=shutil.ignore_patterns("__pycache__", ".pytest_cache", "*.pyc"))
        env = environment(scratch)
        for block in blocks:
            run_block(block, scratch, env, markers, update, result)
    return result


def run_block(block: Block, scratch: Path, env: dict[str, str], markers: set[str] | None,
              update: bool, result: PageResult) -> None:
    options = block.options
    if block.title:
        (scratch / block.title).write_text("\n".join(block.body) + "\n", encoding="utf-8")
    if block.language not in RUN_LANGUAGES | LISTING_LANGUAGES:
        return
    listed = [(c.text, c.line) for c in block.commands] if block.commands else [
        (line.rstrip("\\").strip(), block.line + 1 + row)
        for row, line in enumerate(block.body) if line.strip()]
    if block.language in LISTING_LANGUAGES and options.skip is None:
        result.failures.append(
            f"{block.where()}: a ```{block.language} block is not run: write it as a ```console "
            "block with '$ ' prompts and the output, or put <!-- docs-run: skip='REASON' --> "
            "before it")
        return
    reason = options.skip
    if reason is None and markers is not None and not set(options.needs) <= markers:
        reason = f"needs {', '.join(options.needs)} (its pytest marker selects it)"
    if reason is None and unavailable(options):
        reason = f"needs {'; '.join(unavailable(options))}: not available here"
    if reason is not None:
        result.skipped.append(f"block {block.number} (line {block.line}): {reason}")
        for text, line in listed:
            result.failures += check_listing(block, text, line, scratch)
        return
    for command in block.commands:
        must_fail = options.fails and command is block.commands[-1]
        try:
            done = subprocess.run(
                ["bash", "-c", command.text], cwd=scratch, env=env, stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=options.timeout_s,
                check=False,
            )
        except subprocess.TimeoutExpired:
            result.failures.append(f"{block.where(command.line)}: `{command.text}` ran longer "
                                   f"than {options.timeout_s:g} s (timeout=SECONDS raises it)")
            continue
        result.ran += 1
        actual = done.stdout.decode("utf-8", "replace").splitlines()
        actual = [line.rstrip() for line in actual]
        while actual and not actual[-1]:
            actual.pop()
        if (done.returncode != 0) != must_fail:
            tail = "\n".join("    " + line for line in actual[-15:])
            expectation = "exit non-zero (the block is marked fails)" if must_fail else "succeed"
            result.failures.append(f"{block.where(command.line)}: `{command.text}` exited with "
                                   f"status {done.returncode}; it should {expectation}\n{tail}")
            continue
        if update:
            new = regenerated(command.expected, actual, options.masks)
            if new != command.expected:
                result.updates[command.output_start] = new
                result.spans[command.output_start] = command.output_end
        elif not matches(command.expected, actual, options.masks):
            result.failures.append(difference(block, command, actual))


def write_updates(result: PageResult, indent_of: dict[int, str]) -> None:
    lines = result.page.read_text(encoding="utf-8").splitlines()
    for start in sorted(result.updates, reverse=True):
        indent = indent_of.get(start, "")
        lines[start:result.spans[start]] = [(indent + line).rstrip() for line in result.updates[start]]
    result.page.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("pages", nargs="*", type=Path, help="pages to check (default: all)")
    parser.add_argument("--update", action="store_true",
                        help="rewrite the shown outputs from what the commands print now")
    args = parser.parse_args(argv)
    chosen = [path.resolve() for path in args.pages] or pages()
    failed = 0
    for page in chosen:
        if not page.is_file():
            print(f"{page}: no such page", file=sys.stderr)
            return 2
        result = run_page(page, update=args.update)
        if args.update and result.updates:
            indents = {c.output_start: b.indent for b in parse_page(page) for c in b.commands}
            write_updates(result, indents)
        status = "FAIL" if result.failures else "ok"
        extra = f", {len(result.updates)} output(s) rewritten" if result.updates else ""
        print(f"{status}  {relative(page)}: {result.ran} command(s) ran, "
              f"{len(result.skipped)} block(s) skipped{extra}")
        for skipped in result.skipped:
            print(f"      skipped {skipped}")
        for failure in result.failures:
            print(failure, file=sys.stderr)
        failed += bool(result.failures)
    return 1 if failed else 0


if __name__ == "__main__":
    try:
        raise SystemExit(main())
    except BrokenPipeError:  # `run_docs.py | head`: stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise SystemExit(141) from None
