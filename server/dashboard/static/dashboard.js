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
