// The alarms page (templates/_alarms.html), loaded after hmi.js:
// - "5 min ago" / "in 25 min" ([data-ago]: seconds since the epoch) stay true while the page
//   is open, on the station's clock (.alarm-book[data-now]) whatever this device's says;
// - when the list is re-fetched (SSE `alarm`), an alarm a person has opened stays open and
//   a note being typed stays (details[data-keep]); after a form's own answer they close;
// - an alarm opened scrolls its Acknowledge button into view (a watch shows little).
(() => {
  "use strict";

  let offset = 0; // the station's clock minus this device's, in seconds

  // the same words as app.web.routes.alarms.relative
  function relative(seconds) {
    if (seconds >= 0 && seconds < 45) return "just now";
    const minutes = Math.max(1, Math.floor((Math.abs(seconds) + 30) / 60));
    let span;
    if (minutes < 60) span = `${minutes} min`;
    else if (minutes < 24 * 60) span = `${Math.floor(minutes / 60)} h`;
    else span = `${Math.floor(minutes / (24 * 60))} d`;
    return seconds >= 0 ? `${span} ago` : `in ${span}`;
  }

  function readClock() {
    const book = document.querySelector(".alarm-book[data-now]");
    const now = Number(book?.dataset.now);
    if (Number.isFinite(now)) offset = now - Date.now() / 1000;
  }

  function refresh() {
    const now = Date.now() / 1000 + offset;
    document.querySelectorAll("[data-ago]").forEach((el) => {
      const at = Number(el.dataset.ago);
      if (Number.isFinite(at)) el.textContent = relative(now - at);
    });
  }

  let kept = null; // {open: Set of data-keep, notes: Map "keep|name" -> value}
  document.addEventListener("htmx:beforeSwap", (event) => {
    const target = event.detail.target;
    if (target?.id !== "alarms") return;
    const verb = event.detail.requestConfig?.verb;
    if (verb !== "get") {
      kept = null; // a form's answer: what it acted on is done
      return;
    }
    kept = { open: new Set(), notes: new Map() };
    target.querySelectorAll("details[data-keep][open]").forEach((d) => {
      kept.open.add(d.dataset.keep);
      d.querySelectorAll("input[type=text], input[type=number]").forEach((input) => {
        kept.notes.set(`${d.dataset.keep}|${input.closest("form")?.action}|${input.name}`, input.value);
      });
    });
  });

  document.addEventListener("htmx:afterSwap", (event) => {
    if (event.detail.target?.id !== "alarms") return;
    if (kept) {
      event.detail.target.querySelectorAll("details[data-keep]").forEach((d) => {
        if (!kept.open.has(d.dataset.keep)) return;
        d.open = true;
        d.querySelectorAll("input[type=text], input[type=number]").forEach((input) => {
          const value = kept.notes.get(`${d.dataset.keep}|${input.closest("form")?.action}|${input.name}`);
          if (value !== undefined) input.value = value;
        });
      });
      kept = null;
    }
    readClock();
    refresh();
  });

  // an alarm opened on a small screen: its first button (Acknowledge) scrolled into view,
  // so the answer is a tap away without hunting for it ("toggle" does not bubble)
  document.addEventListener(
    "toggle",
    (event) => {
      const details = event.target;
      if (!(details instanceof HTMLDetailsElement) || !details.open) return;
      if (!details.closest("#alarms")) return;
      details.querySelector("form button")?.scrollIntoView({ block: "nearest" });
    },
    true,
  );

    document.addEventListener("DOMContentLoaded", () => {
    readClock();
    refresh();
    setInterval(refresh, 15000);
  });
})();
