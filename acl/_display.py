"""Notebook display shared by every result type (acl.notebook) and the sweep and tune tables: a small HTML
table and matplotlib Axes that a notebook shows as their figure.  No heavy import at module level."""
from __future__ import annotations


def new_axes(ax=None, size=(6.0, 3.5)):
    """``ax`` itself, or the Axes of a new Figure made without pyplot (the global backend is untouched)."""
    if ax is not None:
        return ax
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    ax = fig.add_subplot()
    shown(ax)
    return ax


def shown(ax):
    """``ax``, displayed in a notebook as its figure: a Figure made without pyplot is not shown by the
    inline backend, so `x.plot()` as a cell's last line showed `<Axes: ...>` (issue 28); the Axes
    carries ``_repr_png_`` (IPython's display hook looks it up on the object) rendering its figure."""
    def _repr_png_():
        import io

        from matplotlib.backends.backend_agg import FigureCanvasAgg

        fig = ax.figure
        if not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        return buf.getvalue()

    ax._repr_png_ = _repr_png_
    return ax


def html_table(title: str, header: list, rows: list, note: str = "") -> str:
    """A small HTML table (every cell escaped): the notebook display of every result (acl.notebook, the sweep
    and tune tables)."""
    import html

    esc = html.escape
    head = "".join(f"<th>{esc(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{esc(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    foot = f"<p><small>{esc(note)}</small></p>" if note else ""
    return (f"<div><strong>{esc(title)}</strong><table><thead><tr>{head}</tr></thead>"
            f"<tbody>{body}</tbody></table>{foot}</div>")
