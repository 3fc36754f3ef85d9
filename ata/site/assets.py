"""The results page's style sheet and script, written into the page's folder beside it: nothing
is fetched when the page is viewed. The script sorts a table by the column whose header is
clicked (or given Enter): numbers by value, text by its letters, a blank cell always last; a
second click turns the order round."""

CSS = """\
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto;
       max-width: 1320px; padding: 0 16px 48px; color: #1d2330; }
h1 { margin: 24px 0 4px; } h2 { margin-top: 32px; border-bottom: 1px solid #dfe3ea; }
a { color: #1a5fb4; }
code, pre { font: 13px/1.4 ui-monospace, "DejaVu Sans Mono", monospace; }
pre { background: #f4f6f9; padding: 8px 12px; overflow-x: auto; }
table { border-collapse: collapse; margin: 8px 0 16px; font-size: 14px; }
th, td { padding: 4px 8px; border-bottom: 1px solid #e6e9ef; text-align: right;
         white-space: nowrap; }
td.text, th.text { text-align: left; }
th { white-space: normal; vertical-align: bottom; }
.scroll { overflow-x: auto; }
table.sortable th { cursor: pointer; user-select: none; background: #f4f6f9; }
table.sortable th:hover { background: #e6ebf2; }
th[aria-sort="ascending"]::after { content: " \\25B2"; font-size: 10px; }
th[aria-sort="descending"]::after { content: " \\25BC"; font-size: 10px; }
.tier { display: inline-block; padding: 0 6px; border-radius: 8px; font-size: 12px; }
.tier.reproduced { background: #d7f2dd; color: #17612b; }
.tier.reported { background: #eceff3; color: #4a5160; }
.ahead { font-weight: 600; }
tr.seeds td { background: #f6f8fc; }
.note { color: #5b6373; font-size: 13px; }
figure { margin: 16px 0 28px; } figure img { max-width: 100%; border: 1px solid #e6e9ef; }
figcaption { font-size: 13px; color: #4a5160; }
dl { display: grid; grid-template-columns: max-content auto; gap: 2px 16px; }
dt { font-weight: 600; } dd { margin: 0; }
"""

JS = """\
(function () {
  "use strict";
  function key(td) {
    var v = td.getAttribute("data-v");
    if (v === null) { v = td.textContent; }
    if (v === "") { return null; }
    var n = Number(v);
    return isNaN(n) ? v.toLowerCase() : n;
  }
  function compare(x, y) {
    if (typeof x === typeof y) { return x < y ? -1 : x > y ? 1 : 0; }
    return typeof x === "number" ? -1 : 1;
  }
  function sortBy(table, th, col) {
    var ascending = th.getAttribute("aria-sort") !== "ascending";
    var heads = table.tHead.rows[0].cells;
    for (var i = 0; i < heads.length; i++) { heads[i].removeAttribute("aria-sort"); }
    th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows).map(function (row, i) {
      return { row: row, key: key(row.cells[col]), i: i };
    });
    rows.sort(function (a, b) {
      if (a.key === null || b.key === null) {
        return a.key === b.key ? a.i - b.i : a.key === null ? 1 : -1;
      }
      var c = compare(a.key, b.key);
      return (ascending ? c : -c) || a.i - b.i;
    });
    rows.forEach(function (r) { body.appendChild(r.row); });
  }
  var tables = document.querySelectorAll("table.sortable");
  Array.prototype.forEach.call(tables, function (table) {
    var heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, col) {
      th.tabIndex = 0;
      th.title = "sort by this column";
      th.addEventListener("click", function () { sortBy(table, th, col); });
      th.addEventListener("keydown", function (e) {
        if (e.key === "Enter") { sortBy(table, th, col); }
      });
    });
  });
})();
"""
