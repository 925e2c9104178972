"""A minimal XML tree that remembers the line of every element (for file/line errors).

Files come from other people: a document type declaration (DTD) is refused, so that no
entity can be declared and expanded (a "billion laughs" file of a few hundred bytes would
otherwise grow to gigabytes), and elements may nest MAX_DEPTH deep at most.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import overload
from xml.parsers import expat

from baarda.errors import ProjectError
from baarda.io.text_files import file_bytes


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

    @overload
    def value(self, tag: str, default: str) -> str: ...

    @overload
    def value(self, tag: str, default: None = None) -> str | None: ...

    def value(self, tag: str, default: str | None = None) -> str | None:
        c = self.find(tag)
        return default if c is None else c.text.strip()


MAX_DEPTH = 256  # DBAT scripts nest 5 deep
MAX_BYTES = 256 * 2**20  # project descriptions, not data: 256 MB at most


class _Refused(Exception):
    """Raised inside the expat handlers; carries the ProjectError to raise."""


def parse_xml(path: str | Path) -> Node:
    """Parse an XML file into Nodes; ProjectError with the line of a syntax error."""
    p = Path(path)
    try:
        size = p.stat().st_size if p.is_file() else 0
    except OSError as e:
        raise ProjectError(str(path), f"cannot be read ({e.strerror or e})") from None
    if size > MAX_BYTES:
        raise ProjectError(str(path), f"{size} bytes: larger than an XML project "
                           f"description can be ({MAX_BYTES} bytes)")
    return parse_xml_bytes(file_bytes(p), str(path))


def parse_xml_bytes(data: bytes, path: str) -> Node:
    """Parse XML `data` (named `path` in errors, e.g. "project.psz!doc.xml") into Nodes."""
    if len(data) > MAX_BYTES:
        raise ProjectError(path, f"{len(data)} bytes: larger than an XML project "
                           f"description can be ({MAX_BYTES} bytes)")
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[Node] = []
    root: list[Node] = []

    def refuse(message: str):
        raise _Refused(ProjectError(str(path), message, parser.CurrentLineNumber))

    def doctype(*_):
        refuse("the file declares a document type (<!DOCTYPE ...>): refused, because its "
               "entities could expand without bound; remove the declaration")

    def start(tag, attrib):
        if len(stack) >= MAX_DEPTH:
            refuse(f"elements nested deeper than {MAX_DEPTH} levels")
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

    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = doctype
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except _Refused as e:
        raise e.args[0] from None
    except expat.ExpatError as e:
        raise ProjectError(str(path), f"not valid XML: {expat.ErrorString(e.code)}",
                           e.lineno) from None
    except (LookupError, ValueError) as e:  # the encoding of <?xml ... encoding="..."?>
        raise ProjectError(str(path), f"the encoding that the XML declaration names cannot "
                           f"be read ({e}); use UTF-8", parser.CurrentLineNumber or 1,
                           "encoding") from None
    if not root:
        raise ProjectError(str(path), "no XML element")
    return root[0]
