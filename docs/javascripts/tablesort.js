/* mobman's site: every data table sorts by the column whose header is clicked (mkdocs.yml extra_javascript; the
   header buttons and the sort arrow are styled in stylesheets/extra.css; tests/test_docs_tablesort.py drives it in
   a headless Chromium).

   Tables: those Material styles as data tables (`.md-typeset table:not([class])`: every Markdown table, so the
   scorecards written by `mobman-eval bench` need no marker) with a header row and at least two body rows.
   Each header's content moves into a <button> (focusable; Enter and Space click it); the sorted header carries
   aria-sort="ascending" or "descending". The first click sorts ascending, each further click reverses.
   A column is numeric when every cell that is not empty or a dash starts with a number, read as the scorecards
   print them: `91% [88-94]` is 91, `~4000` is 4000, `1.33e+03` is 1330, `2.5 s` is 2.5; empty and dash cells
   (`-`: no value) go last in either direction. Any other column sorts as text (case-insensitive, digits in
   names by value: ladder-2.5s before ladder-10s). Equal keys keep the page's order.
   Runs on every page Material shows: its `document$` emits each page, including those of instant navigation;
   without Material, on DOMContentLoaded. No network, no library. */
(function () {
  "use strict";

  // an optional approximation or bound sign, then a decimal number, ending at the cell's end or a non-alphanumeric
  // character: "5 s", "91%", "1.09 [1.05-1.13]" are numbers; "2e1595b" (a commit) and "ur5" are not
  var NUMBER = /^[~≈<>≤≥]?\s*([+\-−]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+\-]?\d+)?)(?![\w.])/;
  var MISSING = /^(?:[-–—]?|n\/a|nan)$/i;
  var TEXT = new Intl.Collator(undefined, { numeric: true, sensitivity: "base" });

  function cellText(row, index) {
    var cell = row.cells[index];
    return cell ? cell.textContent.trim() : "";
  }

  function numberOf(text) {
    var match = NUMBER.exec(text);
    return match ? parseFloat(match[1].replace("−", "-")) : NaN;
  }

  // "number" when every present cell of the column reads as a number (and one at least is present), else "text"
  function kindOf(rows, index) {
    var present = 0;
    for (var i = 0; i < rows.length; i++) {
      var text = cellText(rows[i], index);
      if (MISSING.test(text)) continue;
      if (isNaN(numberOf(text))) return "text";
      present++;
    }
    return present ? "number" : "text";
  }

  // body rows of `table` (in its page order `original`) sorted by column `index`; `sign` 1 ascending, -1 descending
  function sortRows(table, original, index, sign) {
    var kind = kindOf(original, index);
    var keyed = original.map(function (row, order) {
      var text = cellText(row, index);
      var key = MISSING.test(text) ? null : kind === "number" ? numberOf(text) : text;
      return { row: row, key: key, order: order };
    });
    keyed.sort(function (a, b) {
      if (a.key === null || b.key === null) {
        return a.key === b.key ? a.order - b.order : a.key === null ? 1 : -1;  // missing last, both ways
      }
      var c = kind === "number" ? a.key - b.key : TEXT.compare(a.key, b.key);
      return c ? sign * c : a.order - b.order;
    });
    var body = table.tBodies[0];
    keyed.forEach(function (k) {
      body.appendChild(k.row);
    });
  }

  function makeSortable(table) {
    if (table.hasAttribute("data-sortable") || !table.tHead || !table.tBodies.length) return;
    var headRow = table.tHead.rows[table.tHead.rows.length - 1];
    var original = Array.prototype.slice.call(table.tBodies[0].rows);
    if (!headRow || original.length < 2) return;
    table.setAttribute("data-sortable", "");
    var headers = Array.prototype.slice.call(headRow.cells);
    headers.forEach(function (th, index) {
      var button = document.createElement("button");
      button.type = "button";
      button.className = "mobman-sort";
      button.title = "Sort by this column";
      while (th.firstChild) button.appendChild(th.firstChild);
      th.appendChild(button);
      button.addEventListener("click", function () {
        var ascending = th.getAttribute("aria-sort") !== "ascending";
        headers.forEach(function (other) {
          other.removeAttribute("aria-sort");
        });
        th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
        sortRows(table, original, index, ascending ? 1 : -1);
      });
    });
  }

  function init() {
    var tables = document.querySelectorAll(".md-typeset table:not([class])");
    Array.prototype.forEach.call(tables, makeSortable);
  }

  if (typeof window.document$ !== "undefined" && typeof window.document$.subscribe === "function") {
    window.document$.subscribe(init);
  } else if (document.readyState === "loading") {
    document.addEventListener("DOMContentLoaded", init);
  } else {
    init();
  }
})();
