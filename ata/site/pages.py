"""The results page's HTML: the index (the sets, a leaderboard per setting and level, the
figures) and a page per method of each set (its provenance and the command that reproduces
it). Plain HTML, the style sheet and script of `ata.site.assets` beside it; no date, so the
same sets give the same pages."""

from __future__ import annotations

import math
from html import escape
from typing import Any

from ata.results.report import title
from ata.results.seeds import PairAcross
from ata.runtime.folders import safe_name
from ata.site.board import Board, Entry
from ata.site.seeds import SeedEntry
from ata.site.sources import MethodInfo, Source

NAN = float("nan")
Tier = tuple[str, Any, str]
"""(tier, the record behind it or None, why in a sentence), as `ata.site.verify.tier`."""


def page_name(source: Source, method: str) -> str:
    return f"method-{source.slug}-{safe_name(method, 'method')}.html"


def seeds_page_name(source: Source, group: str) -> str:
    """The page of a method's training seeds (`ata.site.seeds`)."""
    return f"seeds-{source.slug}-{safe_name(group, 'method')}.html"


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


def _diff(paired_n: int, d: float, lo: float, hi: float, unpaired: str) -> str:
    if not paired_n:
        return f'<span title="{escape(unpaired)}">&ndash;</span>'
    ahead = ' class="ahead"' if lo > 0 or hi < 0 else ""
    return f"<span{ahead}>{d:+.1f} [{lo:+.1f}, {hi:+.1f}]</span>"


def _pair_td(pair: PairAcross | None, unpaired: str) -> str:
    """A cell of a difference across seeds (`ata.results.seeds.pair_across`), or why none."""
    if pair is None:
        return _td(_diff(0, NAN, NAN, NAN, unpaired), "")
    return _td(_diff(pair.scenarios, pair.mean, pair.low, pair.high, ""), pair.mean)


def leaderboard(board: Board, setting: str, level: str, tiers: dict[int, Tier],
                order: dict[int, int]) -> list[str]:
    """One (setting, level) table, sorted by mean score, best first: each method, and a method
    with training seeds as one row across its seeds (its seeds' rows are on its page)."""
    base = escape(board.base)
    head = ["tier", "method", "set", "scenarios", "mean score", "95% CI", "fraction of U",
            f"method &minus; {base} [95% CI]", f"P(beats {base})", "s / scenario",
            "training seeds"]
    rows = []
    for e in board.table(setting, level):
        if e.seed_of:
            continue
        name = tiers[order[id(e.source)]][0]
        seeds, seeds_v = _seeds(e.source.methods.get(e.method))
        rows.append((-e.mean, "<tr>" + "".join([
            _td(_tier(name), name, "text"),
            _td(f'<a href="{page_name(e.source, e.method)}">{escape(e.label)}</a>', e.label,
                "text"),
            _td(escape(_set_name(e.source)), e.source.name, "text"),
            _td(str(e.n), e.n),
            _td(f"{e.mean:.1f}", e.mean),
            _td(f"[{e.low:.1f}, {e.high:.1f}]", e.low),
            _td(_num(e.fraction_of_u, ".3f"), e.fraction_of_u),
            _td(_diff(e.paired_n, *e.diff, e.unpaired), e.diff[0] if e.paired_n else ""),
            _td(_num(e.beats, ".3f"), e.beats),
            _td(_num(e.time_s, ".3g"), e.time_s if e.time_s is not None else ""),
            _td(seeds, seeds_v)]) + "</tr>"))
    for g in board.seed_table(setting, level):
        name = tiers[order[id(g.source)]][0]
        st, pair = g.stats, g.pair
        two = ' title="two-level bootstrap: seeds, then scenarios"' if st.two_level else ""
        rows.append((-st.mean, '<tr class="seeds">' + "".join([
            _td(_tier(name), name, "text"),
            _td(f'<a href="{seeds_page_name(g.source, g.group)}">{escape(g.label)}</a>',
                g.label, "text"),
            _td(escape(_set_name(g.source)), g.source.name, "text"),
            _td(f"{st.scenarios} &times; {st.seeds}", st.scenarios * st.seeds),
            _td(f"{st.mean:.1f}", st.mean),
            _td(f"<span{two}>[{st.low:.1f}, {st.high:.1f}]</span>", st.low),
            _td(_num(g.fraction_of_u, ".3f"), g.fraction_of_u),
            _pair_td(pair, g.unpaired),
            _td(_num(g.beats, ".3f"), g.beats),
            _td(_num(g.time_s, ".3g"), g.time_s if g.time_s is not None else ""),
            _td(f"{st.seeds} ({', '.join(map(str, g.seeds))})", st.seeds)]) + "</tr>"))
    anchor = f"{setting}-{level}"
    return [f'<h2 id="{escape(anchor)}">{escape(title(setting, level).capitalize())}</h2>',
            f'<div class="scroll"><table class="sortable" id="table-{escape(anchor)}">',
            _head(head), "<tbody>", *[r for _, r in sorted(rows, key=lambda r: r[0])],
            "</tbody>", "</table></div>"]


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
            "training runs of a learned method's weights.</p>",
            "<p>A method trained from several seeds (the rows of NAME seed S) has one row "
            "across its seeds, shaded: over the scenarios every seed ran (scenarios &times; "
            "seeds), the mean over the seeds, its 95% interval and the difference to "
            f"{base} from the two-level bootstrap (seeds, then scenarios), and the share of "
            f"(seed, scenario) pairs where a seed scores more than {base}. Its page has the "
            "statistics across seeds (IQM, spread, P(a seed beats)) and each seed's row. "
            "A plain NAME beside the seeds is another run (the default weights) with its own "
            "row.</p>"]
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


def seeds_html(source: Source, group: str, rows: list[SeedEntry], members: list[Entry],
               tier: Tier, base: str) -> str:
    """The page of a method's training seeds: per cell, the seeds as one (`ata.site.seeds`:
    `ata report`'s statistics across seeds), against the base and against the set's plain run
    of the method (its default weights) where it has one, then each seed's row."""
    label = rows[0].label
    name, _, why = tier
    b, g = escape(base), escape(group)
    body = ['<p><a href="index.html">&larr; all results</a></p>', f"<h1>{escape(label)}</h1>",
            "<dl>", f"<dt>set</dt><dd>{escape(_set_name(source))}</dd>",
            f"<dt>tier</dt><dd>{_tier(name)} {escape(why)}</dd>",
            f"<dt>seeds</dt><dd>{escape(', '.join(rows[0].methods))}</dd>", "</dl>",
            f"<p>The rows of {g}'s training seeds ({g} seed S), per "
            "cell: the mean over the seeds of their mean scores, on the scenarios every seed "
            "ran, with its 95% interval from the two-level bootstrap (a resample draws the "
            "seeds, then the scenarios, one scenario draw for every seed and for the other "
            "method of a pair), the interquartile mean of the seeds' means with its interval, "
            "and the spread of the seeds' means. P(a seed beats B) is the share of (seed, "
            "run of B) pairs whose mean over the paired scenarios is higher for the seed, ties "
            f"counting half. {g} (one run), where the set has it, is the plain {g} beside "
            "the seeds: another run (the default weights).</p>",
            "<h2>Across seeds</h2>", '<div class="scroll"><table class="sortable" '
            'id="table-seeds">',
            _head(["cell", "seeds", "scenarios", "mean score [95% CI]", "IQM [95% CI]",
                   "seed means: lowest to highest (sd)", f"&minus; {b} [95% CI]",
                   f"P(a seed beats {b})", f"&minus; {g} (one run) [95% CI]",
                   f"P(a seed beats {g} (one run))"]), "<tbody>"]
    for r in rows:
        st, pair, dflt = r.stats, r.pair, r.default
        spread = "&ndash;" if st.seeds == 1 else \
            f"{st.lowest:.1f} to {st.highest:.1f} ({st.sd:.1f})"
        body.append("<tr>" + "".join([
            _td(r.cell, r.cell, "text"), _td(str(st.seeds), st.seeds),
            _td(str(st.scenarios), st.scenarios),
            _td(f"{st.mean:.1f} [{st.low:.1f}, {st.high:.1f}]", st.mean),
            _td(f"{st.iqm:.1f} [{st.iqm_low:.1f}, {st.iqm_high:.1f}]", st.iqm),
            _td(spread, st.highest - st.lowest if st.seeds > 1 else ""),
            _pair_td(pair, r.unpaired),
            _td(_num(pair.beats if pair else None, ".2f"), pair.beats if pair else ""),
            _pair_td(dflt, f"the set has no {group}"),
            _td(_num(dflt.beats if dflt else None, ".2f"), dflt.beats if dflt else "")])
            + "</tr>")
    body += ["</tbody>", "</table></div>", "<h2>Each seed</h2>",
             '<div class="scroll"><table class="sortable" id="table-each-seed">',
             _head(["cell", "seed", "scenarios", "mean score [95% CI]",
                    f"method &minus; {b} [95% CI]", f"P(beats {b})", "s / scenario"]),
             "<tbody>"]
    for e in members:
        body.append("<tr>" + "".join([
            _td(e.cell, e.cell, "text"),
            _td(f'<a href="{page_name(e.source, e.method)}">{escape(e.label)}</a>', e.label,
                "text"),
            _td(str(e.n), e.n), _td(f"{e.mean:.1f} [{e.low:.1f}, {e.high:.1f}]", e.mean),
            _td(_diff(e.paired_n, *e.diff, e.unpaired), e.diff[0] if e.paired_n else ""),
            _td(_num(e.beats, ".3f"), e.beats),
            _td(_num(e.time_s, ".3g"), e.time_s if e.time_s is not None else "")]) + "</tr>")
    body += ["</tbody>", "</table></div>",
             "<p>Each seed's page holds its provenance: its code, weights and missions.</p>"]
    return _page(f"ATA results: {label}", body)
