// Sequence Planner HMI: small glue for every page (loaded by templates/base.html after htmx).
// - every htmx request carries the CSRF token from <meta name="csrf-token">;
// - the top bar's connection indicator follows the SSE connection (#conn); while the
//   connection is down the page says so unmistakably: <body data-offline>, which greys the
//   task card area (hmi.css), the banner #offline ("No connection since HH:MM — tasks may be
//   missing") and a vibration when it drops and another when it comes back;
// - an SSE "alarm" event whose data is a count (or JSON {count, priority, tasks}) updates
//   #alarm-count; `tasks` (also the data of the "tasks" event) the task count on the Tasks
//   tab ([data-task-count]) and in the title;
// - data-confirm="question?" on a form, submit button, link or htmx element asks confirm() first
//   (htmx's own hx-confirm works as usual);
// - forms with data-once send once (no double "Done");
// - a live part with data-seen sends the digest of what it shows as `seen` (204 if unchanged);
// - a form with data-reset-on-success is reset after its own request succeeded;
// - after the live connection dropped and came back, every live part (hx-trigger "sse:…")
//   re-fetches what it shows; the server sends the badge (event "badge") on every connect;
// - the operator's card (#tasks .task-now): a new one vibrates, notifies (once permission
//   was given: asked once, on a tap) and sets the tab's title; one the station has reminded
//   the person of (data-overdue) vibrates a reminder; after a tap the page goes back to the
//   top so the next card shows whole;
// - #alerts (pages of roles that see tasks): "Tap to turn on alerts" while the browser blocks
//   vibration (no tap on the page yet) or has not been allowed to notify; how to allow
//   notifications when they are blocked;
// - an SSE "signed-out" event (the session ended: signed out elsewhere, a new role, a reset
//   password) takes the page to the sign-in page, which then opens it under the new role.
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

  // ---- vibration patterns: each situation its own, told apart without looking ----
  const BUZZ = {
    card: [200, 100, 200], // a new card
    overdue: [400, 150, 400, 150, 400], // a card the station has reminded the person of
    lost: [600, 200, 100, 200, 100], // the live connection dropped: long, then short ones
    back: [100, 100, 100], // it came back
    alerts: [150], // alerts turned on
  };
  function buzz(pattern) {
    if (typeof navigator.vibrate !== "function") return;
    try {
      navigator.vibrate(pattern);
    } catch {
      // a browser that refuses: the banner and the card must do
    }
  }

  // ---- the task count: the Tasks tab and the title of every page ----
  const COUNTED = /^\(\d+\) /;
  const pageTitle = document.title.replace(COUNTED, ""); // "Alarms · Station"
  let taskCount = null; // null: this page shows no count (a role without tasks)
  function renderTitle() {
    const now = document.querySelector("#tasks .task-now");
    const card = now?.dataset.key ? `${now.dataset.title} \u00b7 ` : "";
    document.title = (taskCount ? `(${taskCount}) ` : "") + card + pageTitle;
  }
  function setTaskCount(count) {
    const tabs = document.querySelectorAll("[data-task-count]");
    if (!tabs.length || !Number.isInteger(count) || count < 0) return;
    taskCount = count;
    tabs.forEach((el) => {
      el.dataset.taskCount = String(count);
      el.textContent = count ? ` (${count})` : "";
    });
    renderTitle();
  }
  document.addEventListener("DOMContentLoaded", () => {
    const shown = document.querySelector("[data-task-count]")?.dataset.taskCount;
    if (shown !== undefined) taskCount = Number(shown) || 0;
  });

  // ---- connection indicator and the offline state ----
  const CONN_TEXT = { wait: "connecting", live: "live", down: "disconnected" };
  const pad = (n) => String(n).padStart(2, "0");
  function setConnection(state) {
    const el = document.getElementById("conn");
    if (!el || el.dataset.state === state) return;
    const was = el.dataset.state;
    el.dataset.state = state;
    el.querySelector(".conn__text").textContent = CONN_TEXT[state];
    const banner = signedOut ? null : document.getElementById("offline");
    if (state === "down") {
      const since = new Date();
      document.body.dataset.offline = "true";
      if (banner) {
        banner.querySelector(".offline__since").textContent =
          `${pad(since.getHours())}:${pad(since.getMinutes())}`;
        banner.hidden = false;
      }
      if (was === "live") buzz(BUZZ.lost); // a drop, not a page that never got through
    } else if (state === "live") {
      delete document.body.dataset.offline;
      if (banner) banner.hidden = true;
      if (was === "down") buzz(BUZZ.back);
    }
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

  function parsed(event) {
    try {
      return JSON.parse(event.data);
    } catch {
      return null; // not a count: pages refresh themselves with hx-trigger="sse:…"
    }
  }

  function onAlarmEvent(event) {
    const data = parsed(event);
    if (Number.isInteger(data)) setAlarmCount(data);
    else if (data && Number.isInteger(data.count)) setAlarmCount(data.count, data.priority);
    if (data && Number.isInteger(data.tasks)) setTaskCount(data.tasks);
  }

  function onTasksEvent(event) {
    const data = parsed(event);
    if (data && Number.isInteger(data.tasks)) setTaskCount(data.tasks);
  }

  // the session ended (signed out elsewhere, a new role): sign in again, back to this page;
  // a page with typed text not sent yet (the model editor) stays, and says so
  let signedOut = false;
  function onSignedOut(event) {
    const to = typeof event.data === "string" && event.data.startsWith("/") ? event.data : "/login";
    const here = window.location.pathname + window.location.search;
    const typed = [...document.querySelectorAll("textarea, input[type=text], input:not([type])")]
      .some((el) => el.value !== el.defaultValue);
    if (!typed) {
      window.location.assign(`${to}?next=${encodeURIComponent(here)}`);
      return;
    }
    const banner = document.getElementById("offline");
    if (!banner || signedOut) return;
    signedOut = true;
    banner.textContent = "You were signed out: copy what you typed, then sign in again.";
    banner.hidden = false;
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
      source.addEventListener("tasks", onTasksEvent);
      source.addEventListener("signed-out", onSignedOut);
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
  let shownKey = null;
  let overdueKey = null;
  function cardShown(isNew) {
    const now = document.querySelector("#tasks .task-now");
    if (!now) return;
    const key = now.dataset.key || null;
    setTaskCount(Number(now.dataset.count || 0));
    renderTitle();
    if (isNew && key && key !== shownKey) {
      buzz(BUZZ.card);
      if ("Notification" in window && Notification.permission === "granted") {
        try {
          new Notification(now.dataset.title, { tag: "sp-task", renotify: true });
        } catch {
          // a browser that notifies from a service worker only: the vibration must do
        }
      }
    }
    // the station reminded the person: once per card, also on a page opened late
    const overdue = now.querySelector("[data-overdue='true']") ? key : null;
    if (overdue && overdue !== overdueKey) buzz(BUZZ.overdue);
    overdueKey = overdue;
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

  // ---- "Tap to turn on alerts" ----
  const notifying = () => ("Notification" in window ? Notification.permission : "unsupported");
  let alertsTapped = false;
  function showAlertsPrompt() {
    const box = document.getElementById("alerts");
    if (!box) return;
    const blocked = navigator.userActivation?.hasBeenActive === false;
    const button = box.querySelector(".alerts__turn-on");
    const denied = box.querySelector(".alerts__denied");
    button.hidden = alertsTapped || !(blocked || notifying() === "default");
    denied.hidden = notifying() !== "denied";
    box.hidden = button.hidden && denied.hidden;
  }
  document.addEventListener("DOMContentLoaded", showAlertsPrompt);
  document.addEventListener("click", (event) => {
    if (!event.target.closest?.("#alerts .alerts__turn-on")) return;
    alertsTapped = true;
    buzz(BUZZ.alerts); // allowed now: this tap is the user activation vibrate waited for
    showAlertsPrompt();
    if (notifying() !== "default") return;
    try {
      localStorage.setItem("sp-notify-asked", "1");
    } catch {
      // asked anyway: the person tapped for it
    }
    Promise.resolve(Notification.requestPermission())
      .catch(() => {})
      .then(showAlertsPrompt);
  });

  // ---- the password form: what the browser can tell is told before it is sent ----
  // (the station never writes a password back into a page: a refusal it sends empties them)
  function checkNewPassword(form) {
    const { current_password: current, new_password: fresh, repeat } = form.elements;
    let problem = "";
    if (fresh.value && current.value && fresh.value === current.value) {
      problem = "Choose a password other than the current one.";
    }
    fresh.setCustomValidity(problem);
    const differs = repeat.value && repeat.value !== fresh.value;
    repeat.setCustomValidity(differs ? "The two passwords differ." : "");
  }
  document.addEventListener("input", (event) => {
    const form = event.target.closest?.("form[data-new-password]");
    if (form) checkNewPassword(form);
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
