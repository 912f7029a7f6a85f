// Sorting and filtering for the results site's tables: no framework, no network.
(function () {
  "use strict";
  function cellValue(row, i, kind) {
    var cell = row.cells[i];
    if (!cell) { return kind === "number" ? -Infinity : ""; }
    var raw = cell.hasAttribute("data-value") ? cell.getAttribute("data-value") : cell.textContent.trim();
    if (kind === "number") { var n = parseFloat(raw); return isNaN(n) ? -Infinity : n; }
    return raw.toLowerCase();
  }
  function makeSortable(table) {
    var heads = table.tHead ? table.tHead.rows[0].cells : [];
    Array.prototype.forEach.call(heads, function (th, i) {
      var kind = th.getAttribute("data-sort");
      if (!kind) { return; }
      th.addEventListener("click", function () {
        var ascending = !th.classList.contains("asc");
        Array.prototype.forEach.call(heads, function (h) { h.classList.remove("asc", "desc"); });
        th.classList.add(ascending ? "asc" : "desc");
        var body = table.tBodies[0];
        var rows = Array.prototype.slice.call(body.rows);
        rows.sort(function (a, b) {
          var x = cellValue(a, i, kind), y = cellValue(b, i, kind);
          return (x < y ? -1 : x > y ? 1 : 0) * (ascending ? 1 : -1);
        });
        rows.forEach(function (r) { body.appendChild(r); });
      });
    });
  }
  function applyFilters(tableId) {
    var table = document.getElementById(tableId);
    if (!table) { return; }
    var controls = document.querySelectorAll("[data-filter-table='" + tableId + "']");
    var shown = 0;
    Array.prototype.forEach.call(table.tBodies[0].rows, function (row) {
      var visible = true;
      Array.prototype.forEach.call(controls, function (c) {
        var value = c.value.trim().toLowerCase();
        if (!value) { return; }
        var attr = c.getAttribute("data-filter-attr");
        var text = attr ? (row.getAttribute("data-" + attr) || "").toLowerCase() : row.textContent.toLowerCase();
        if (attr ? text !== value : text.indexOf(value) < 0) { visible = false; }
      });
      row.hidden = !visible;
      if (visible) { shown += 1; }
    });
    var count = document.querySelector("[data-count-for='" + tableId + "']");
    if (count) { count.textContent = shown + " of " + table.tBodies[0].rows.length + " shown"; }
  }
  document.addEventListener("DOMContentLoaded", function () {
    Array.prototype.forEach.call(document.querySelectorAll("table.sortable"), makeSortable);
    var ids = {};
    Array.prototype.forEach.call(document.querySelectorAll("[data-filter-table]"), function (c) {
      var id = c.getAttribute("data-filter-table");
      ids[id] = true;
      c.addEventListener("input", function () { applyFilters(id); });
      c.addEventListener("change", function () { applyFilters(id); });
    });
    Object.keys(ids).forEach(applyFilters);
  });
}());
