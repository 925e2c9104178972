"""Rows of an HTML table, for the report tests."""

from html.parser import HTMLParser


class TableRows(HTMLParser):
    """Rows (class, cell texts) of the table with a given id."""

    def __init__(self, table_id: str):
        super().__init__()
        self.id, self.inside, self.rows, self.cell = table_id, False, [], None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table" and a.get("id") == self.id:
            self.inside = True
        elif self.inside and tag == "tr":
            self.rows.append((a.get("class") or "", []))
        elif self.inside and tag == "td":
            self.cell = ""

    def handle_endtag(self, tag):
        if tag == "table":
            self.inside = False
        elif tag == "td" and self.cell is not None:
            self.rows[-1][1].append(self.cell)
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell += data


def table_rows(html: str, table_id: str) -> list[tuple[str, list[str]]]:
    p = TableRows(table_id)
    p.feed(html)
    return [r for r in p.rows if r[1]]
