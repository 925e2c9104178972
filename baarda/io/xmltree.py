"""A minimal XML tree that remembers the line of every element (for file/line errors)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from baarda.errors import ProjectError


@dataclass
class Node:
    tag: str
    attrib: dict[str, str]
    line: int
    children: list[Node] = field(default_factory=list)
    text: str = ""

    def find(self, tag: str) -> Node | None:
        for c in self.children:
            if c.tag == tag:
                return c
        return None

    def findall(self, tag: str) -> list[Node]:
        return [c for c in self.children if c.tag == tag]

    def value(self, tag: str, default: str | None = None) -> str | None:
        c = self.find(tag)
        return default if c is None else c.text.strip()


def parse_xml(path: str | Path) -> Node:
    """Parse an XML file into Nodes; ProjectError with the line of a syntax error."""
    p = Path(path)
    if not p.is_file():
        raise ProjectError(str(path), "file not found")
    parser = expat.ParserCreate()
    stack: list[Node] = []
    root: list[Node] = []

    def start(tag, attrib):
        node = Node(tag, dict(attrib), parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(tag):
        stack.pop()

    def chars(data):
        if stack:
            stack[-1].text += data

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(p.read_bytes(), True)
    except expat.ExpatError as e:
        raise ProjectError(str(path), f"not valid XML: {expat.ErrorString(e.code)}",
                           e.lineno) from None
    if not root:
        raise ProjectError(str(path), "no XML element")
    return root[0]
