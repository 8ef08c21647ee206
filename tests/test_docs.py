"""What a newcomer reads first: a README that is a product page, short sentences, and comments that say why.

Measurements belong in docs/results.md, where they are kept up to date; a figure in a comment goes stale the day
the network is retrained, while the reason it supports stays true.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
MOST_WORDS = 40
CLOCK_TIME = re.compile(r"\b\d{1,2}:\d{2}\b")
TIMING = re.compile(r"\d\s*(ms|us|µs)\b|\d\s*(milliseconds|microseconds)\b")
MSE_FIGURE = re.compile(r"\bMSE:?\s+(of\s+)?\d|\d+\.\d+\s*/\s*\d+\.\d+\s*/\s*\d+\.\d+")
SESSION = re.compile(r"\bsessions?\b", re.IGNORECASE)


def sentences(markdown: str) -> list[str]:
    """The sentences of a Markdown text: code blocks left out, each list item, heading and table cell on its own."""
    text = re.sub(r"```.*?```", " ", markdown, flags=re.DOTALL)
    text = re.sub(r"`[^`]*`", "X", text)  # inline code counts as one word
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link counts as its words
    found = []
    for block in re.split(r"\n\s*\n|\n(?=\s*(?:[-*#>|]|\d+\. ))", text):
        for cell in block.split("|"):
            # A sentence ends at . ! ? or ; followed by a space (not inside a number or an abbreviation like e.g.).
            found += [part for part in re.split(r"(?<=[.!?;])\s+", " ".join(cell.split())) if part.strip()]
    return found


def test_sentences_split_at_their_ends_and_at_cells_items_and_code():
    text = "One two. Three four; five!\n\n- item one\n- item two\n\n| a b | c |\n\n```\nnot. counted. at all\n```\nx `a b c` y."
    assert sentences(text) == ["One two.", "Three four;", "five!", "- item one", "- item two", "a b", "c", "x X y."]


def test_the_readme_is_a_product_page():
    text = README.read_text()
    assert len(text) <= 10_000, f"README.md has {len(text)} characters"
    assert not CLOCK_TIME.findall(text), f"clock times in README.md: {CLOCK_TIME.findall(text)}"
    assert "## Where a pixel comes from" in text[:2_500] and "5. " in text[:2_500], "the pixel map is not on the first screen"


@pytest.mark.parametrize("path", [README, *DOCS], ids=lambda p: p.name)
def test_no_sentence_is_over_40_words(path):
    long = [s for s in sentences(path.read_text()) if len(s.split()) > MOST_WORDS]
    assert not long, f"{path.name}: {len(long)} sentences over {MOST_WORDS} words, the first: {long[0][:200]}"


def comments_and_docstrings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and every docstring line of a Python file."""
    source = path.read_text()
    found = [(t.start[0], t.string) for t in tokenize.generate_tokens(io.StringIO(source).readline)
             if t.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                found += [(node.body[0].lineno + i, line) for i, line in enumerate(doc.splitlines())]
    return found


def test_the_scanner_finds_comments_and_docstrings(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text('"""Module: 3 ms."""\n\n\ndef f():\n    """MSE 12.0 here."""\n    return 1  # session 5\n')
    texts = [text for _, text in comments_and_docstrings(sample)]
    assert texts == ["# session 5", "Module: 3 ms.", "MSE 12.0 here."]
    assert TIMING.search(texts[1]) and MSE_FIGURE.search(texts[2]) and SESSION.search(texts[0])
    assert not MSE_FIGURE.search("MSE (0-255 scale)") and not TIMING.search("the items")


def test_no_comment_holds_a_timing_an_mse_figure_or_a_session():
    found = []
    for folder in ("app", "models", "renderer"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for line, text in comments_and_docstrings(path):
                if TIMING.search(text) or MSE_FIGURE.search(text) or SESSION.search(text):
                    found.append(f"{path.relative_to(ROOT)}:{line}: {text.strip()}")
    assert not found, "measurements belong in docs/results.md:\n" + "\n".join(found)
