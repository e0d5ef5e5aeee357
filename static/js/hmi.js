// Sequence Planner HMI: small glue for every page (loaded by templates/base.html after htmx).
// - every htmx request carries the CSRF token from <meta name="csrf-token">;
// - the top bar's connection indicator follows the SSE connection (#conn);
// - an SSE "alarm" event whose data is a count (or JSON {count, priority}) updates #alarm-count;
// - data-confirm="question?" on a form, submit button, link or htmx element asks confirm() first
//   (htmx's own hx-confirm works as usual);
// - forms with data-once send once (no double "Done");
// - a live part with data-seen sends the digest of what it shows as `seen` (204 if unchanged);
// - a form with data-reset-on-success is reset after its own request succeeded;
// - after the live connection dropped and came back, every live part (hx-trigger "sse:…")
//   re-fetches what it shows; the server sends the badge (event "badge") on every connect;
// - the operator's card (#tasks .task-now): a new one vibrates, notifies (once permission
//   was given: asked once, on a tap) and sets the tab's title; after a tap the page goes
//   back to the top so the next card shows whole.
// No inline handlers (hx-on, js: values): the Content-Security-Policy forbids eval.
(() => {
  "use strict";

  const csrfToken = () => document.querySelector('meta[name="csrf-token"]')?.content || "";

  document.addEventListener("htmx:configRequest", (event) => {
    const token = csrfToken();
    if (token) event.detail.headers["X-CSRF-Token"] = token;
    const el = event.detail.elt;
    if (el?.hasAttribute?.("data-seen")) {
      const shown = el.querySelector(":scope > [data-digest]");
      event.detail.parameters.seen = shown?.dataset.digest || "";
    }
  });

  // not after requests of elements inside the form (its variable select reloads the form)
  document.addEventListener("htmx:afterRequest", (event) => {
    const el = event.detail.elt;
    if (event.detail.successful && el?.matches?.("form[data-reset-on-success]")) el.reset();
  });

  // ---- connection indicator ----
  const CONN_TEXT = { wait: "connecting", live: "live", down: "disconnected" };
  function setConnection(state) {
    const el = document.getElementById("conn");
    if (!el || el.dataset.state === state) return;
    el.dataset.state = state;
    el.querySelector(".conn__text").textContent = CONN_TEXT[state];
  }

  function setAlarmCount(count, priority) {
    const el = document.getElementById("alarm-count");
    if (!el) return;
    el.querySelector(".alarm-count__n").textContent = String(count);
    el.classList.toggle("alarm-count--active", count > 0);
    if (count > 0 && priority) el.dataset.priority = String(priority).toLowerCase();
    else delete el.dataset.priority;
    // the visible words first in the name (WCAG 2.5.3, axe-core's label-content-name-mismatch)
    el.setAttribute("aria-label", `Alarms: ${count} active`);
  }

  function onAlarmEvent(event) {
    let data;
    try {
      data = JSON.parse(event.data);
    } catch {
      return; // not a count: pages refresh themselves with hx-trigger="sse:alarm"
    }
    if (Number.isInteger(data)) setAlarmCount(data);
    else if (data && Number.isInteger(data.count)) setAlarmCount(data.count, data.priority);
  }

  // what was sent while the connection was down is fetched again, not waited for
  function resync() {
    if (!window.htmx) return;
    document.querySelectorAll('[hx-trigger*="sse:"]').forEach((el) => {
      const name = /sse:[\w-]+/.exec(el.getAttribute("hx-trigger"))?.[0];
      if (name) window.htmx.trigger(el, name); // as if the event had come
    });
  }

  const watched = new WeakSet();
  let dropped = false;
  let current = null;
  document.addEventListener("htmx:sseOpen", (event) => {
    setConnection("live");
    const source = event.detail?.source;
    current = source || current;
    if (source && !watched.has(source)) {
      watched.add(source);
      source.addEventListener("alarm", onAlarmEvent);
      source.addEventListener("badge", onAlarmEvent);
    }
    if (dropped) resync();
    dropped = false;
  });
  document.addEventListener("htmx:sseError", () => {
    dropped = true;
    setConnection("down");
  });
  window.addEventListener("offline", () => {
    dropped = true;
    setConnection("down");
  });
  // the stream may have lived through a short drop (no error, no new open): then it is
  // live again as soon as the network is, and what it may have missed is fetched
  window.addEventListener("online", () => {
    if (current && current.readyState === EventSource.OPEN) {
      setConnection("live");
      dropped = false;
      resync();
    }
  });

  // ---- the operator's card ----
  const baseTitle = document.title;
  let shownKey = null;
  function cardShown(isNew) {
    const now = document.querySelector("#tasks .task-now");
    if (!now) return;
    const key = now.dataset.key || null;
    const count = Number(now.dataset.count || 0);
    document.title = key ? `(${count}) ${now.dataset.title} \u00b7 ${baseTitle}` : baseTitle;
    if (isNew && key && key !== shownKey) {
      if (typeof navigator.vibrate === "function") navigator.vibrate([200, 100, 200]);
      if ("Notification" in window && Notification.permission === "granted") {
        try {
          new Notification(now.dataset.title, { tag: "sp-task", renotify: true });
        } catch {
          // a browser that notifies from a service worker only: the vibration must do
        }
      }
    }
    if (key !== shownKey) window.scrollTo(0, 0);
    shownKey = key;
  }
  document.addEventListener("DOMContentLoaded", () => cardShown(false));
  document.addEventListener("htmx:afterSwap", (event) => {
    // a card that arrives by itself is new; the one after a person's own tap is not news
    if (event.detail?.target?.id === "tasks") cardShown(event.detail.requestConfig?.verb === "get");
  });
  // permission to notify: asked once, from a person's own tap on a card, never again
  document.addEventListener("click", (event) => {
    if (!event.target.closest?.("#tasks button")) return;
    if (!("Notification" in window) || Notification.permission !== "default") return;
    try {
      if (localStorage.getItem("sp-notify-asked")) return;
      localStorage.setItem("sp-notify-asked", "1");
    } catch {
      return; // no storage: not asking at all is better than asking on every tap
    }
    Notification.requestPermission().catch(() => {});
  });

  // ---- data-confirm ----
  function confirmed(el) {
    const question = el?.dataset?.confirm;
    return !question || window.confirm(question);
  }

  document.addEventListener(
    "submit",
    (event) => {
      const form = event.target;
      if (!confirmed(event.submitter) || !confirmed(form)) {
        event.preventDefault();
        event.stopImmediatePropagation();
        return;
      }
      if (form.hasAttribute("data-once")) {
        if (form.dataset.sent) {
          event.preventDefault();
          event.stopImmediatePropagation();
          return;
        }
        form.dataset.sent = "1";
        // after the submission has read the form, so the button's name/value still go out
        setTimeout(() => form.querySelectorAll("button").forEach((b) => (b.disabled = true)), 0);
      }
    },
    true,
  );

  document.addEventListener(
    "click",
    (event) => {
      const el = event.target.closest?.("[data-confirm]");
      if (!el || el.tagName === "FORM") return;
      if (el.form && el.type === "submit") return; // asked on submit
      if (!confirmed(el)) {
        event.preventDefault();
        event.stopImmediatePropagation();
      }
    },
    true,
  );

  // back/forward cache: a page shown again must be usable again
  window.addEventListener("pageshow", (event) => {
    if (!event.persisted) return;
    document.querySelectorAll("form[data-once]").forEach((form) => {
      delete form.dataset.sent;
      form.querySelectorAll("button").forEach((b) => (b.disabled = false));
    });
  });

  // ---- the user menu closes on Escape or a tap elsewhere ----
  document.addEventListener("click", (event) => {
    document.querySelectorAll("details.user-menu[open]").forEach((menu) => {
      if (!menu.contains(event.target)) menu.open = false;
    });
  });
  document.addEventListener("keydown", (event) => {
    if (event.key !== "Escape") return;
    document.querySelectorAll("details.user-menu[open]").forEach((menu) => {
      menu.open = false;
      menu.querySelector("summary").focus();
    });
  });
})();
