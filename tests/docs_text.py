"""Sentences of the docs that quote a test's numbers (tests only)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def doc_says(page: str, sentence: str) -> bool:
    """Whether `page` (relative to the repository) holds `sentence`, white space and line
    breaks not counted."""
    text = re.sub(r"\s+", " ", (ROOT / page).read_text(encoding="utf-8"))
    return re.sub(r"\s+", " ", sentence) in text
