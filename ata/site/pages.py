"""The results page's HTML: the index (the sets, a leaderboard per setting and level, the
figures) and a page per method of each set (its provenance and the command that reproduces
it). Plain HTML, the style sheet and script of `ata.site.assets` beside it; no date, so the
same sets give the same pages."""

from __future__ import annotations

import math
from html import escape
from typing import Any

from ata.results.report import title
from ata.runtime.folders import safe_name
from ata.site.board import Board, Entry
from ata.site.sources import MethodInfo, Source

Tier = tuple[str, Any, str]
"""(tier, the record behind it or None, why in a sentence), as `ata.site.verify.tier`."""


def page_name(source: Source, method: str) -> str:
    return f"method-{source.slug}-{safe_name(method, 'method')}.html"


def _page(heading: str, body: list[str], css: str = "site.css") -> str:
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{escape(heading)}</title>", f'<link rel="stylesheet" href="{css}">',
        "</head>", "<body>", *body, '<script src="site.js"></script>', "</body>", "</html>",
        ""])


def _td(text: str, value: Any = None, cls: str = "") -> str:
    """A cell; `value` is what it sorts by (a number, or '' for none)."""
    attrs = f' class="{cls}"' if cls else ""
    if value is not None:
        if isinstance(value, float) and not math.isfinite(value):
            value = ""
        attrs += f' data-v="{escape(str(value))}"'
    return f"<td{attrs}>{text}</td>"


def _num(x: float | None, spec: str) -> str:
    return "&ndash;" if x is None or not math.isfinite(x) else format(x, spec)


def _tier(name: str) -> str:
    return f'<span class="tier {name}">{name}</span>'


def _seed(source: Source) -> str:
    return "public" if source.seed_public else "secret"


def _isolated(source: Source) -> str:
    return {True: "yes (--isolate)", False: "no", None: "not recorded"}[source.isolated]


def _set_name(source: Source) -> str:
    return source.name + (f"@{source.release}" if source.release else "")


def _seeds(info: MethodInfo | None) -> tuple[str, Any]:
    if info is None or not info.learned:
        return "&ndash;", ""
    seeds = info.training_seeds()
    if not seeds:
        return "not recorded", ""
    return f"{len(seeds)} ({', '.join(map(str, seeds))})", len(seeds)


TEXT_HEADS = ("tier", "method", "set", "cell", "seed", "isolated", "machine", "ata")


def _head(names: list[str]) -> str:
    cls = {h: ' class="text"' if h in TEXT_HEADS else "" for h in names}
    return "<thead><tr>" + "".join(f'<th scope="col"{cls[h]}>{h}</th>' for h in names) \
        + "</tr></thead>"


def _machine(info: dict[str, Any]) -> str:
    """A machine record in a line: 'CPU, N cores (python X; numpy Y; torch Z)'."""
    versions = "; ".join(f"{k} {info[k]}" for k in ("python", "numpy", "torch") if k in info)
    return _short_machine(info) + (f" ({versions})" if versions else "")


def _short_machine(info: dict[str, Any]) -> str:
    return f"{info.get('cpu', 'unknown')}, {info.get('cores', '?')} cores" if info else \
        "not recorded"


def leaderboard(board: Board, setting: str, level: str, tiers: dict[int, Tier],
                order: dict[int, int]) -> list[str]:
    """One (setting, level) table, sorted by mean score, best first."""
    base = escape(board.base)
    head = ["tier", "method", "set", "scenarios", "mean score", "95% CI", "fraction of U",
            f"method &minus; {base} [95% CI]", f"P(beats {base})", "s / scenario",
            "training seeds"]
    rows = []
    for e in sorted(board.table(setting, level), key=lambda e: -e.mean):
        name = tiers[order[id(e.source)]][0]
        d, lo, hi = e.diff
        ahead = ' class="ahead"' if e.paired_n and (lo > 0 or hi < 0) else ""
        diff = (f'<span title="{escape(e.unpaired)}">&ndash;</span>' if not e.paired_n else
                f"<span{ahead}>{d:+.1f} [{lo:+.1f}, {hi:+.1f}]</span>")
        seeds, seeds_v = _seeds(e.source.methods.get(e.method))
        rows.append("<tr>" + "".join([
            _td(_tier(name), name, "text"),
            _td(f'<a href="{page_name(e.source, e.method)}">{escape(e.label)}</a>', e.label,
                "text"),
            _td(escape(_set_name(e.source)), e.source.name, "text"),
            _td(str(e.n), e.n),
            _td(f"{e.mean:.1f}", e.mean),
            _td(f"[{e.low:.1f}, {e.high:.1f}]", e.low),
            _td(_num(e.fraction_of_u, ".3f"), e.fraction_of_u),
            _td(diff, d if e.paired_n else ""),
            _td(_num(e.beats, ".3f"), e.beats),
            _td(_num(e.time_s, ".3g"), e.time_s if e.time_s is not None else ""),
            _td(seeds, seeds_v)]) + "</tr>")
    anchor = f"{setting}-{level}"
    return [f'<h2 id="{escape(anchor)}">{escape(title(setting, level).capitalize())}</h2>',
            f'<div class="scroll"><table class="sortable" id="table-{escape(anchor)}">',
            _head(head), "<tbody>", *rows, "</tbody>", "</table></div>"]


def sets_table(sources: list[Source], tiers: dict[int, Tier]) -> list[str]:
    head = ["set", "tier", "rows", "methods", "ata", "seed", "isolated", "machine"]
    rows = []
    for k, src in enumerate(sources):
        name = tiers[k][0]
        rows.append("<tr>" + "".join([
            _td(escape(_set_name(src)), src.name, "text"),
            _td(_tier(name), name, "text"),
            _td(f"{len(src.results.columns['method']):,}", len(src.results.columns["method"])),
            _td(str(len(src.results.methods)), len(src.results.methods)),
            _td(escape(src.ata or "not recorded"), src.ata or "", "text"),
            _td(_seed(src), _seed(src), "text"),
            _td(_isolated(src), _isolated(src), "text"),
            _td(escape(_short_machine(src.machine)), None, "text")]) + "</tr>")
    notes = [f"<li>{escape(_set_name(src))}: {tiers[k][0]}, {escape(tiers[k][2])}.</li>"
             for k, src in enumerate(sources)]
    return ['<div class="scroll"><table class="sortable" id="table-sets">', _head(head),
            "<tbody>", *rows, "</tbody>", "</table></div>", '<ul class="note">', *notes,
            "</ul>"]


def index_html(sources: list[Source], board: Board, tiers: dict[int, Tier],
               figures: list[tuple[str, str]], command: str) -> str:
    """index.html: the sets, the leaderboards, the figures (stem, caption)."""
    order = {id(src): k for k, src in enumerate(sources)}
    base = escape(board.base)
    body = ["<h1>ATA results</h1>",
            f'<p class="note">Built by <code>{escape(command)}</code> from the rows of the '
            "sets below; nothing on this page is typed in. Click a column's header to sort.</p>",
            "<h2>Sets</h2>",
            "<p>A set is <em>reproduced</em> when ata's own rerun of a sample of its rows "
            "(every method and cell) on the code the set names found them identical, and "
            "<em>reported</em> otherwise.</p>",
            *sets_table(sources, tiers),
            "<p>Per team setting and uncertainty level: the mean total team performance over "
            "the scenarios with its 95% percentile-bootstrap interval, the mean fraction of "
            f"the upper bound U, the paired difference method &minus; {base} on the same "
            "scenarios with its 95% bootstrap interval (bold where it excludes 0), the share "
            f"of those scenarios where the method scores more than {base} (ties count half), "
            "the time per scenario on the machine that made the rows, and the seeds of the "
            "training runs of a learned method's weights.</p>"]
    for setting, level in board.groups():
        body += leaderboard(board, setting, level, tiers, order)
    if figures:
        body.append('<h2 id="figures">Figures</h2>')
        for stem, caption in figures:
            body += [f'<figure id="{escape(stem)}">',
                     f'<img src="{escape(stem)}.png" alt="{escape(stem)}">',
                     f"<figcaption>{escape(caption)}</figcaption>", "</figure>"]
    body.append('<p class="note">The same numbers, for programs: '
                '<a href="site.json">site.json</a>.</p>')
    return _page("ATA results", body)


def method_html(source: Source, info: MethodInfo, label: str, entries: list[Entry],
                tier: Tier, base: str) -> str:
    """A method's page: its rows, its provenance, and the command that reproduces them."""
    name, record, why = tier
    packages = ", ".join(f"{k} {v}" for k, v in source.packages.items()) or "not recorded"
    facts = [("set", escape(_set_name(source))), ("tier", f"{_tier(name)} {escape(why)}"),
             ("ata", escape(source.ata or "not recorded")),
             ("model revision", escape(source.model_revision or "not recorded")),
             ("git commit", escape(source.commit or "not recorded")),
             ("packages", escape(packages)),
             ("machine", escape(_machine(source.machine)) if source.machine
              else "not recorded"),
             ("decisions isolated", _isolated(source)), ("seed", _seed(source))]
    if record is not None:
        facts.append(("rerun", f"{record.get('per_cell')} scenario(s) per cell, ata "
                               f"{escape(str(record.get('ata')))}"))
    body = ['<p><a href="index.html">&larr; all results</a></p>',
            f"<h1>{escape(label)}</h1>", "<dl>",
            *[f"<dt>{k}</dt><dd>{v}</dd>" for k, v in facts], "</dl>",
            "<h2>Rows</h2>", '<table class="sortable" id="table-rows">',
            _head(["cell", "scenarios", "mean score [95% CI]", "fraction of U",
                   f"method &minus; {escape(base)} [95% CI]", "s / scenario"]), "<tbody>"]
    for e in entries:
        d, lo, hi = e.diff
        body.append("<tr>" + "".join([
            _td(e.cell, e.cell, "text"), _td(str(e.n), e.n),
            _td(f"{e.mean:.1f} [{e.low:.1f}, {e.high:.1f}]", e.mean),
            _td(_num(e.fraction_of_u, ".3f"), e.fraction_of_u),
            _td(f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]" if e.paired_n else "&ndash;",
                d if e.paired_n else ""),
            _td(_num(e.time_s, ".3g"), e.time_s if e.time_s is not None else "")]) + "</tr>")
    body += ["</tbody>", "</table>", "<h2>Code</h2>",
             "<p>The digest of each component's code (ata's <code>plugins.toml</code>) and the "
             "version it came with.</p>", "<table>",
             '<thead><tr><th class="text">component</th><th class="text">code digest</th>'
             '<th class="text">version</th></tr></thead>',
             "<tbody>"]
    body += [f'<tr><td class="text">{escape(k)}</td><td class="text"><code>{escape(v)}</code></td>'
             f'<td class="text">{escape(info.versions.get(k, ""))}</td></tr>'
             for k, v in info.code.items()]
    body += ["</tbody>", "</table>", *_cells(source, info)]
    return _page(f"ATA results: {label}", body)


def _cells(source: Source, info: MethodInfo) -> list[str]:
    """Per cell: its scenarios, model revision, weights and resolved mission, with the
    commands that run it again and compare."""
    out = ["<h2>Cells</h2>"]
    for cell, c in info.cells.items():
        first, count = (c.get("scenarios") or ["?", "?"])[:2]
        out += [f"<h3>{escape(cell)}</h3>", "<dl>",
                f"<dt>scenarios</dt><dd>{count} from id {first}, root seed "
                f"{escape(c['seed'] if source.seed_public else 'secret')}</dd>",
                f"<dt>model revision</dt><dd><code>{escape(str(c.get('model')))}</code></dd>"]
        for w in info.weights.get(cell, []):
            seeds = (f"trainer seed {w.seeds[0]}; its training scenarios' root seeds "
                     + ", ".join(map(str, w.seeds))) if w.seeds else "seeds not recorded"
            out.append(f"<dt>weights</dt><dd><code>{escape(w.spec)}</code> "
                       f"({escape(w.setting)}, digest <code>{escape(w.digest)}</code>; "
                       f"trained: {escape(', '.join(w.trained) or 'not recorded')}; "
                       f"{escape(seeds)})</dd>")
        out.append("</dl>")
        if source.kind == "published":
            spec = escape(source.spec)
            out += ["<p>To run this cell again: save the mission below as "
                    "<code>mission.toml</code>, then</p>",
                    f"<pre>ata run mission.toml -o runs/rerun\n"
                    f"ata compare runs/rerun {spec} --base {escape(info.name)}</pre>",
                    "<p>(every difference 0: the rows are reproduced).</p>"]
        elif source.command:
            out.append(f"<p>Made by</p><pre>{escape(source.command)}</pre>")
        if c.get("mission"):
            out += ["<details><summary>resolved mission</summary>",
                    f"<pre>{escape(c['mission'])}</pre></details>"]
    return out
