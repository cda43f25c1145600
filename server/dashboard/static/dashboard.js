// Keeps a dashboard page current without a reload: polls the page's JSON endpoint
// (data-poll on <main>, the page's own filters and page included), swaps in the
// server-rendered fragments it carries, and redraws the pictures when new points or a new
// surrogate version arrive. A hidden tab does not poll; it catches up when shown again.
(function () {
  "use strict";

  async function redraw(box) {
    const response = await fetch(box.dataset.src, { cache: "no-store" });
    if (response.ok) box.innerHTML = await response.text();
  }

  function withParam(box, name, value) {
    const url = new URL(box.dataset.src, window.location.href);
    if (url.searchParams.get(name) === value) return false;
    url.searchParams.set(name, value);
    box.dataset.src = url.pathname + url.search;
    return true;
  }

  // A figure of panels asks for as many a row as its box holds: on a phone they stack, their
  // text at full size, rather than shrink until it cannot be read.
  function fitColumns() {
    for (const box of document.querySelectorAll(".figure[data-panel-px]")) {
      const room = box.clientWidth - 16;
      const fits = Math.floor(room / Number(box.dataset.panelPx));
      const cols = Math.max(1, Math.min(Number(box.dataset.maxCols), fits));
      if (withParam(box, "cols", String(cols))) redraw(box);
    }
  }
  let resized = null;
  window.addEventListener("resize", function () {
    window.clearTimeout(resized);
    resized = window.setTimeout(fitColumns, 300);
  });
  fitColumns();

  // The history's axis: time (idle pauses left out), points or runs.
  for (const choice of document.querySelectorAll(".axis-choice")) {
    const box = document.getElementById(choice.dataset.figure);
    choice.addEventListener("click", function (event) {
      const button = event.target.closest("button[data-axis]");
      if (!button || !box) return;
      for (const b of choice.querySelectorAll("button")) {
        b.setAttribute("aria-pressed", String(b === button));
      }
      if (withParam(box, "axis", button.dataset.axis)) redraw(box);
    });
  }

  // Sortable tables: a click on a column's heading sorts the rows shown by it (numbers as
  // numbers; a cell's data-sort wins over its text), again to reverse; kept across polls.
  const sorted = {};
  function cellKey(row, column) {
    const cell = row.children[column];
    if (!cell) return "";
    return cell.dataset.sort !== undefined ? cell.dataset.sort : cell.textContent.trim();
  }
  function applySort(table) {
    const state = sorted[table.id];
    const body = table.tBodies[0];
    if (!state || !body) return;
    const rows = Array.from(body.rows).filter((r) => r.children.length > 1);
    const keys = rows.map((r) => cellKey(r, state.column));
    const numeric = keys.every((k) => k === "" || !Number.isNaN(Number(k)));
    const order = rows.map((row, k) => [row, keys[k]]);
    order.sort(function (p, q) {
      const a = numeric ? Number(p[1] || -Infinity) : p[1];
      const b = numeric ? Number(q[1] || -Infinity) : q[1];
      return (a < b ? -1 : a > b ? 1 : 0) * state.direction;
    });
    for (const [row] of order) body.appendChild(row);
    for (const th of table.tHead.rows[0].cells) th.removeAttribute("aria-sort");
    const th = table.tHead.rows[0].cells[state.column];
    th.setAttribute("aria-sort", state.direction > 0 ? "ascending" : "descending");
  }
  document.addEventListener("click", function (event) {
    const th = event.target.closest("table.sortable thead th");
    if (!th) return;
    const table = th.closest("table");
    const before = sorted[table.id];
    const direction = before && before.column === th.cellIndex ? -before.direction : 1;
    sorted[table.id] = { column: th.cellIndex, direction: direction };
    applySort(table);
  });

  const main = document.querySelector("main[data-poll]");
  const live = document.getElementById("live");
  if (!main) {
    if (live) live.textContent = "";
    return;
  }
  const every = 5000;
  let timer = null;
  let running = false;
  const figureEvery = 10000;
  let figuresAt = 0;

  function setLive(text, ok) {
    if (!live) return;
    live.textContent = text;
    live.classList.toggle("stale", !ok);
  }

  // The pictures (heat map, slices, history) are redrawn when their key changes (new points
  // or a new surrogate version), at most once every figureEvery ms.
  async function refreshFigures(key) {
    if (key === undefined || Date.now() - figuresAt < figureEvery) return;
    const stale = Array.from(document.querySelectorAll(".live-figure")).filter(
      (box) => box.dataset.key !== key
    );
    if (stale.length === 0) return;
    figuresAt = Date.now();
    for (const box of stale) {
      const response = await fetch(box.dataset.src, { cache: "no-store" });
      if (!response.ok) continue;
      box.innerHTML = await response.text();
      box.dataset.key = key;
    }
  }

  function schedule(delay) {
    window.clearTimeout(timer);
    timer = null;
    if (document.visibilityState === "visible") timer = window.setTimeout(tick, delay);
  }

  async function tick() {
    if (running) return;
    running = true;
    try {
      const response = await fetch(main.dataset.poll, {
        cache: "no-store",
        headers: { Accept: "application/json" },
      });
      if (!response.ok) throw new Error("HTTP " + response.status);
      const data = await response.json();
      // A fragment the user is working in (a select open, a field typed in) waits for the
      // next poll; one that did not change is left alone.
      for (const [id, html] of Object.entries(data.fragments || {})) {
        const element = document.getElementById(id);
        if (!element || element.contains(document.activeElement)) continue;
        if (element.dataset.html !== html) {
          element.innerHTML = html;
          element.dataset.html = html;
          for (const table of element.querySelectorAll("table.sortable")) applySort(table);
        }
      }
      await refreshFigures(data.figure_key);
      setLive("live · " + new Date().toLocaleTimeString(), true);
    } catch (error) {
      setLive("cannot reach the service (" + error.message + "), retrying", false);
    } finally {
      running = false;
      schedule(every);
    }
  }

  document.addEventListener("visibilitychange", function () {
    if (document.visibilityState === "visible") {
      schedule(0);
    } else {
      schedule(every);
      setLive("paused while hidden", true);
    }
  });
  setLive("live", true);
  schedule(every);
})();
