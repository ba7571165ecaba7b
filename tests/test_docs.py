"""The documentation is true: the API reference builds from the docstrings without a
complaint, and every command line the docs show names real subcommands and flags."""

import re
import shlex
import sys

import pytest
from paths import ROOT

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

ROOT = ROOT
DOCS = [ROOT / "README.md", ROOT / "examples" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_the_api_reference_builds_with_every_module(tmp_path):
    pytest.importorskip("pdoc")
    sys.path.insert(0, str(ROOT / "docs"))
    try:
        import build_api
    finally:
        sys.path.remove(str(ROOT / "docs"))
    assert build_api.build(tmp_path) == []
    pages = {p.relative_to(tmp_path).with_suffix("").as_posix().replace("/", ".")
             for p in tmp_path.rglob("*.html")}  # fmt: skip
    assert set(build_api.modules()) <= pages
    text = (tmp_path / "gridsim" / "envs" / "gridsim_env.html").read_text()
    assert "GridSimEnv" in text and "reward_space" in text


def _command_lines():
    """``(file, program, words)`` of every ``gridsim ...`` / ``neurotrajectory ...`` line of
    the docs' shell blocks (continuations joined, comments and prompts dropped)."""
    for doc in DOCS:
        for block in re.findall(r"```(?:bash|sh|shell)\n(.*?)```", doc.read_text(), re.S):
            for line in block.replace("\\\n", " ").splitlines():
                lexer = shlex.shlex(line.strip().removeprefix("$ "), posix=True,
                                    punctuation_chars=True)  # fmt: skip
                lexer.whitespace_split, lexer.commenters = True, "#"
                words: list[str] = []
                for token in [*lexer, ";"]:
                    if token not in ("&&", ";", "|", "||", "&"):
                        words.append(token)
                        continue
                    if words and words[0] in ("gridsim", "neurotrajectory"):
                        yield doc.name, words[0], words[1:]
                    words = []


def _subcommands(program: str) -> dict:
    from gridsim.cli import build_parser as gridsim_parser
    from neurotrajectory.cli import build_parser as nt_parser

    parser = gridsim_parser() if program == "gridsim" else nt_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return {name: {o for a in p._actions for o in a.option_strings}
            for name, p in sub.choices.items()}  # fmt: skip


def test_every_command_in_the_docs_exists_with_its_flags():
    lines = list(_command_lines())
    assert len(lines) > 30  # the docs do show commands
    problems = []
    for doc, program, words in lines:
        commands = _subcommands(program)
        if not words or words[0] not in commands:
            problems.append(f"{doc}: {program} {' '.join(words[:1])}: no such subcommand")
            continue
        for w in words[1:]:
            flag = w.split("=")[0]
            if flag.startswith("--") and flag not in commands[words[0]]:
                problems.append(f"{doc}: {program} {words[0]} {flag}: no such flag")
    assert problems == []


def test_every_python_block_in_the_docs_is_valid_python():
    blocks = [(doc.name, b) for doc in DOCS
              for b in re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)]  # fmt: skip
    assert len(blocks) > 5
    for name, block in blocks:
        compile(block, name, "exec")  # a SyntaxError names the file
