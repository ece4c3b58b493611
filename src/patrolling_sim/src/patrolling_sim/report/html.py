"""Self-contained HTML page: tables plus PNG figures embedded as base64 data URIs."""
import base64
import html
import math

_CSS = """
body{font-family:sans-serif;margin:1.5em auto;max-width:1300px;color:#222;padding:0 1em}
h1{font-size:1.6em} h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.8em}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #bbb;padding:.25em .6em;text-align:right}
th{background:#eef} td.t{text-align:left}
td.sig{background:#fdd} .warn{color:#a50} .note{color:#555;font-size:.9em}
img{max-width:100%;border:1px solid #ddd;margin:.4em 0}
figure{margin:0 0 1.2em 0} figcaption{font-size:.9em;color:#444}
details{margin:.6em 0}
"""


def esc(x):
    return html.escape(str(x))


def is_nan(x):
    return isinstance(x, float) and math.isnan(x)


def table(header, rows, text_cols=(), cell_class=None):
    """header: list of str; rows: list of lists of already formatted str.
    cell_class(row_index, col_index) -> css class or None."""
    out = ["<table><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>"]
    for i, r in enumerate(rows):
        cells = []
        for j, v in enumerate(r):
            cls = []
            if j in text_cols:
                cls.append("t")
            if cell_class:
                c = cell_class(i, j)
                if c:
                    cls.append(c)
            attr = f' class="{" ".join(cls)}"' if cls else ""
            cells.append(f"<td{attr}>{esc(v)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def image(path, caption):
    with open(path, "rb") as f:
        data = base64.b64encode(f.read()).decode("ascii")
    return (f'<figure><img alt="{esc(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def page(title, sections):
    """sections: list of (heading or None, html body)."""
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>{esc(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{esc(title)}</h1>"]
    for heading, body in sections:
        if heading:
            parts.append(f"<h2>{esc(heading)}</h2>")
        parts.append(body)
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"
