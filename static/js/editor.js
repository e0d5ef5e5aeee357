// A small YAML editor for station models: line numbers, syntax highlighting, error marks.
// No dependencies. Contract (see templates that use it):
//
//   <div class="editor" data-editor [data-errors="#model-errors"]>
//     <textarea name="text" spellcheck="false">…yaml…</textarea>
//   </div>
//   <ul id="model-errors"><li data-line="84" data-column="21">message</li>…</ul>
//
// The textarea stays the real form field (it works without this script). Its text is made
// transparent and a highlighted <pre aria-hidden="true"> mirror is laid exactly under it, one
// block <span class="editor-line"> per line; the mirror and gutter follow the textarea's scroll
// by a transform. Each input re-highlights only the lines that changed (plus following lines
// whose tokenizer state changed, e.g. an opened quote), so large models stay responsive.
//
// window.sequenceEditor.markErrors([{line, column, message}]) marks lines in the gutter and the
// mirror and writes each message in a note in the editor's own strip under the code, in the
// layout's flow: it takes room from the code and never covers a line of it; [] clears. After
// any htmx swap the error list (default #model-errors) is read again. Clicking an error puts the caret there.
// Tab inserts two spaces (Shift+Tab outdents); Escape then Tab leaves the editor.
(() => {
  "use strict";

  // ---- highlighting -------------------------------------------------------------------------
  const ESCAPES = { "&": "&amp;", "<": "&lt;", ">": "&gt;" };
  const esc = (s) => s.replace(/[&<>]/g, (c) => ESCAPES[c]);
  const tok = (cls, s) => (s ? `<span class="tok-${cls}">${esc(s)}</span>` : "");

  // expression operators and {parameter} placeholders inside strings of this model language
  const OPERATORS = /&&|\|\||==|!=|:=|->|!|\{[A-Za-z_][\w.]*\}/g;
  function expression(s) {
    let out = "";
    let last = 0;
    for (const m of s.matchAll(OPERATORS)) {
      out += esc(s.slice(last, m.index)) + tok(m[0][0] === "{" ? "param" : "op", m[0]);
      last = m.index + m[0].length;
    }
    return out + esc(s.slice(last));
  }
  const str = (s) => (s ? `<span class="tok-str">${expression(s)}</span>` : "");

  const NUMBER =
    /^(?:[-+]?(?:\d[\d_]*(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|0x[\dA-Fa-f]+|0o[0-7]+|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$/;
  // YAML 1.1 as PyYAML reads it: yes/no/on/off are booleans too
  const BOOLEAN =
    /^(?:true|True|TRUE|false|False|FALSE|yes|Yes|YES|no|No|NO|on|On|ON|off|Off|OFF|null|Null|NULL|~)$/;
  const FLOW = ",[]{}";

  // index of the closing quote at or after `from`, or -1 when the string continues
  function closingQuote(text, from, quote) {
    for (let k = from; k < text.length; k++) {
      const c = text[k];
      if (quote === '"' && c === "\\") k++;
      else if (c === quote) {
        if (quote === "'" && text[k + 1] === "'") k++;
        else return k;
      }
    }
    return -1;
  }

  // Tokenizer state between lines: q open quote, b block scalar parent column (-1: none),
  // f flow nesting depth. Returns [html, state after the line].
  const START = Object.freeze({ q: "", b: -1, f: 0 });
  const sameState = (a, b) => a.q === b.q && a.b === b.b && a.f === b.f;

  function highlightLine(text, state) {
    let { q, b, f } = state;
    const n = text.length;
    const indent = /^ */.exec(text)[0].length;
    if (b >= 0) {
      if (indent === n || indent > b) return [str(text), state]; // block scalar content
      b = -1;
    }
    let out = "";
    let i = 0;
    if (q) {
      const end = closingQuote(text, 0, q);
      if (end < 0) return [str(text), state];
      out += str(text.slice(0, end + 1));
      i = end + 1;
      q = "";
    }
    if (/^(?:---|\.\.\.)(?:\s|$)/.test(text)) {
      out += tok("punct", text.slice(0, 3));
      i = 3;
    }
    let nodeStart = true; // where a new node may begin: line start, after "- ", ": ", "[", "{", ","
    let nodeColumn = indent; // column of the last key or dash: a block scalar's parent
    while (i < n) {
      const c = text[i];
      const next = text[i + 1];
      if (c === " " || c === "\t") {
        const j = text.slice(i).search(/[^ \t]|$/) + i;
        out += text.slice(i, j);
        i = j;
      } else if (c === "#" && (i === 0 || text[i - 1] === " " || text[i - 1] === "\t")) {
        out += tok("comment", text.slice(i));
        break;
      } else if (c === '"' || c === "'") {
        const end = closingQuote(text, i + 1, c);
        if (end < 0) {
          out += str(text.slice(i));
          q = c;
          break;
        }
        const s = text.slice(i, end + 1);
        i = end + 1;
        out += /^[ \t]*:(?:[ \t]|$)/.test(text.slice(i)) ? tok("key", s) : str(s);
        nodeStart = false;
      } else if (c === "-" && nodeStart && (next === undefined || next === " " || next === "\t")) {
        out += tok("dash", c);
        nodeColumn = i;
        i++;
      } else if ((c === "&" || c === "*" || c === "!") && nodeStart && next && !/[\s,[\]{}]/.test(next)) {
        const j = text.slice(i).search(/[\s,[\]{}]|$/) + i;
        out += tok(c === "!" ? "tag" : "anchor", text.slice(i, j));
        if (c === "*") nodeStart = false;
        i = j;
      } else if (FLOW.includes(c) && (c === "[" || c === "{" ? nodeStart : f > 0)) {
        out += tok("punct", c);
        if (c === "[" || c === "{") f++;
        else if (c !== ",") f--;
        nodeStart = c !== "]" && c !== "}";
        i++;
      } else if (c === ":" && (next === undefined || next === " " || next === "\t" || (f > 0 && FLOW.includes(next)))) {
        out += tok("punct", c);
        nodeStart = true;
        i++;
      } else if ((c === "|" || c === ">") && nodeStart && /^[|>][-+0-9]*[ \t]*(?:#.*)?$/.test(text.slice(i))) {
        const m = /^([|>][-+0-9]*)([ \t]*)(.*)$/.exec(text.slice(i));
        out += tok("punct", m[1]) + m[2] + tok("comment", m[3]);
        b = nodeColumn;
        break;
      } else {
        // plain scalar: up to ": ", " #", or a flow indicator inside flow collections
        let j = i;
        for (; j < n; j++) {
          const d = text[j];
          const e = text[j + 1];
          if (d === ":" && (e === undefined || e === " " || e === "\t" || (f > 0 && FLOW.includes(e)))) break;
          if (d === "#" && (text[j - 1] === " " || text[j - 1] === "\t")) break;
          if (f > 0 && FLOW.includes(d)) break;
        }
        if (j === i) j++;
        const raw = text.slice(i, j);
        const s = raw.replace(/[ \t]+$/, "");
        if (j < n && text[j] === ":") {
          out += tok("key", s);
          nodeColumn = i;
        } else if (NUMBER.test(s)) out += tok("num", s);
        else if (BOOLEAN.test(s)) out += tok("bool", s);
        else out += expression(s);
        out += raw.slice(s.length);
        nodeStart = false;
        i = j;
      }
    }
    return [out, { q, b, f: Math.max(f, 0) }];
  }

  // ---- the editor ---------------------------------------------------------------------------
  const editors = [];

  class Editor {
    constructor(root) {
      this.root = root;
      this.textarea = root.querySelector("textarea");
      this.errorsSelector = root.dataset.errors || "#model-errors";
      this.lines = [];
      this.states = [START]; // states[k]: tokenizer state before line k (one more than lines)
      this.marks = []; // [{line, column, message}], 1-based
      this.listKey = null;
      this.escapeTab = false;
      this.build();
      this.update();
      this.readErrorList();
    }

    build() {
      const ta = this.textarea;
      ta.setAttribute("wrap", "off");
      ta.spellcheck = false;
      ta.setAttribute("autocapitalize", "off");
      ta.setAttribute("autocomplete", "off");
      this.root.classList.add("editor--on");

      this.gutter = document.createElement("div");
      this.gutter.className = "editor-gutter";
      this.gutter.setAttribute("aria-hidden", "true");
      this.gutterInner = document.createElement("div");
      this.gutter.append(this.gutterInner);

      this.body = document.createElement("div");
      this.body.className = "editor-body";
      this.mirror = document.createElement("pre");
      this.mirror.className = "editor-mirror";
      this.mirror.setAttribute("aria-hidden", "true");
      this.code = document.createElement("code");
      this.code.className = "editor-code";
      this.mirror.append(this.code);
      this.notes = document.createElement("div");
      this.notes.className = "editor-notes";
      this.notes.setAttribute("aria-hidden", "true");
      this.notesLayer = document.createElement("div");
      this.notesLayer.className = "editor-notes__layer";
      this.notes.append(this.notesLayer);
      this.measure = document.createElement("span");
      this.measure.className = "editor-measure";
      this.measure.textContent = "0".repeat(50);

      ta.replaceWith(this.body);
      this.body.append(this.mirror, ta, this.measure);
      this.root.prepend(this.gutter);
      this.root.append(this.notes);
      this.notes.hidden = true;
      this.notes.addEventListener("click", (e) => {
        const note = e.target.closest?.(".editor-note");
        if (note) this.goTo(Number(note.dataset.line), Number(note.dataset.column) || 1);
      });

      ta.addEventListener("input", () => this.update());
      ta.addEventListener("scroll", () => this.sync(), { passive: true });
      ta.addEventListener("keydown", (e) => this.onKey(e));
      for (const type of ["keyup", "click", "select", "focus"]) {
        ta.addEventListener(type, () => this.fadeNotesAtCaret());
      }
      ta.addEventListener("blur", () => this.fadeNotesAtCaret(true));
    }

    get lineHeight() {
      return parseFloat(getComputedStyle(this.mirror).lineHeight) || 22;
    }

    get charWidth() {
      return this.measure.getBoundingClientRect().width / 50 || 9.6;
    }

    // Re-highlight what changed since the last call; keep error marks on their (moved) lines.
    update() {
      const lines = this.textarea.value.split("\n");
      const old = this.lines;
      const delta = lines.length - old.length;
      // common prefix, never including a last line (its span has no trailing newline)
      const limit = Math.max(0, Math.min(old.length, lines.length) - 1);
      let p = 0;
      while (p < limit && old[p] === lines[p]) p++;
      let s = 0;
      while (s < Math.min(old.length, lines.length) - p && old[old.length - 1 - s] === lines[lines.length - 1 - s]) s++;

      const changedEnd = lines.length - s;
      const htmls = [];
      const states = [];
      let state = this.states[p];
      let i = p;
      while (i < lines.length) {
        if (i >= changedEnd && sameState(state, this.states[i - delta])) break;
        states.push(state);
        const [html, after] = highlightLine(lines[i], state);
        htmls.push(html);
        state = after;
        i++;
      }
      const oldEnd = i - delta;

      const children = this.code.children;
      const template = document.createElement("template");
      template.innerHTML = htmls
        .map((h, k) => `<span class="editor-line">${h}${p + k < lines.length - 1 ? "\n" : ""}</span>`)
        .join("");
      for (let k = oldEnd - 1; k >= p; k--) children[k].remove();
      this.code.insertBefore(template.content, children[p] || null);
      this.states = this.states.slice(0, p).concat(states, this.states.slice(oldEnd));
      if (i === lines.length) this.states[lines.length] = state;
      this.states.length = lines.length + 1;
      this.lines = lines;

      const gutterLines = this.gutterInner.children;
      while (gutterLines.length < lines.length) {
        const ln = document.createElement("div");
        ln.className = "editor-ln";
        ln.textContent = String(gutterLines.length + 1);
        this.gutterInner.append(ln);
      }
      while (gutterLines.length > lines.length) gutterLines[gutterLines.length - 1].remove();

      if (this.marks.length && (delta || htmls.length)) {
        const suffixStart = old.length - s; // 0-based first old line of the unchanged tail
        for (const mark of this.marks) {
          if (mark.line - 1 >= suffixStart) mark.line += delta;
          mark.line = Math.min(Math.max(mark.line, 1), lines.length);
        }
        this.renderMarks();
      }
      this.sync();
      this.fadeNotesAtCaret();
    }

    sync() {
      const { scrollTop: top, scrollLeft: left } = this.textarea;
      this.code.style.transform = `translate(${-left}px, ${-top}px)`;
      this.gutterInner.style.transform = `translateY(${-top}px)`;
    }

    markErrors(list, { reveal = true } = {}) {
      this.marks = (list || [])
        .map((e) => ({
          line: Math.trunc(Number(e.line)) || 1,
          column: Math.max(1, Math.trunc(Number(e.column)) || 1),
          message: String(e.message ?? ""),
        }))
        .map((e) => ({ ...e, line: Math.min(Math.max(e.line, 1), this.lines.length) }));
      this.renderMarks();
      if (reveal && this.marks.length) {
        const first = this.marks.reduce((a, e) => (e.line < a.line ? e : a));
        this.reveal(first.line, first.column);
      }
    }

    renderMarks() {
      for (const el of this.root.querySelectorAll(".is-error")) el.classList.remove("is-error");
      this.notesLayer.replaceChildren();
      const byLine = new Map();
      for (const mark of this.marks) {
        if (!byLine.has(mark.line)) byLine.set(mark.line, []);
        byLine.get(mark.line).push(mark);
      }
      for (const [line, marks] of byLine) {
        this.code.children[line - 1]?.classList.add("is-error");
        this.gutterInner.children[line - 1]?.classList.add("is-error");
        const note = document.createElement("div");
        note.className = "editor-note";
        note.dataset.line = String(line);
        note.dataset.column = String(marks[0].column);
        for (const [k, mark] of marks.entries()) {
          if (k) note.append(document.createElement("br"));
          note.append(mark.message);
        }
        this.notesLayer.append(note);
      }
      this.notes.hidden = byLine.size === 0;
      this.fadeNotesAtCaret();
    }

    // The note of the line the caret is on stands out (the notes never cover the code).
    fadeNotesAtCaret(blurred = false) {
      const ta = this.textarea;
      const focused = !blurred && document.activeElement === ta;
      let caretLine = 0;
      if (focused) caretLine = ta.value.slice(0, ta.selectionStart).split("\n").length;
      for (const note of this.notesLayer.children) {
        note.classList.toggle("is-at-caret", focused && Number(note.dataset.line) === caretLine);
      }
    }

    // Scroll the textarea so that line/column is in view, and the editor into the page's view.
    reveal(line, column = 1) {
      const ta = this.textarea;
      const lh = this.lineHeight;
      const top = (line - 1) * lh;
      if (top < ta.scrollTop || top + 3 * lh > ta.scrollTop + ta.clientHeight) {
        ta.scrollTop = Math.max(0, top - Math.round(ta.clientHeight / 3));
      }
      const x = (column - 1) * this.charWidth;
      if (x < ta.scrollLeft || x > ta.scrollLeft + ta.clientWidth - 8 * this.charWidth) {
        ta.scrollLeft = Math.max(0, x - Math.round(ta.clientWidth / 3));
      }
      this.sync();
      const box = this.root.getBoundingClientRect();
      if (box.top < 0 || box.bottom > window.innerHeight) {
        this.root.scrollIntoView({ block: box.height > window.innerHeight ? "start" : "nearest" });
      }
    }

    goTo(line, column = 1) {
      const ta = this.textarea;
      const l = Math.min(Math.max(line, 1), this.lines.length);
      let offset = 0;
      for (let k = 0; k < l - 1; k++) offset += this.lines[k].length + 1;
      offset += Math.min(Math.max(column, 1) - 1, this.lines[l - 1].length);
      ta.focus({ preventScroll: true });
      ta.setSelectionRange(offset, offset);
      this.reveal(l, column);
      this.fadeNotesAtCaret();
    }

    // Read the server's error list; reveal the first error unless the user is typing here.
    readErrorList() {
      const list = document.querySelector(this.errorsSelector);
      if (!list) return;
      const items = [...list.querySelectorAll("li[data-line]")].map((li) => {
        li.tabIndex = 0;
        return { line: li.dataset.line, column: li.dataset.column || 1, message: li.textContent.trim() };
      });
      const key = JSON.stringify(items);
      if (key === this.listKey) return;
      this.listKey = key;
      this.markErrors(items, { reveal: document.activeElement !== this.textarea });
    }

    onKey(e) {
      if (e.key === "Escape") {
        this.escapeTab = true;
        return;
      }
      if (e.key !== "Tab" || e.ctrlKey || e.altKey || e.metaKey) {
        if (e.key !== "Shift") this.escapeTab = false;
        return;
      }
      if (this.escapeTab) {
        this.escapeTab = false; // Escape, Tab: let the focus move on
        return;
      }
      e.preventDefault();
      const ta = this.textarea;
      const { selectionStart: start, selectionEnd: end, value } = ta;
      const multiline = value.slice(start, end).includes("\n");
      if (!e.shiftKey && !multiline) {
        replaceText(ta, start, end, "  ");
        return;
      }
      const from = value.lastIndexOf("\n", start - 1) + 1;
      const to = end > start && value[end - 1] === "\n" ? end - 1 : end;
      const block = value.slice(from, to);
      const changed = e.shiftKey
        ? block.replace(/^ {1,2}/gm, "")
        : block.replace(/^/gm, "  ");
      if (changed === block) return;
      replaceText(ta, from, to, changed);
      ta.setSelectionRange(from, from + changed.length);
    }
  }

  // Replace a range as if typed (keeps the browser's undo history where it can).
  function replaceText(ta, start, end, text) {
    ta.setSelectionRange(start, end);
    let done = false;
    try {
      done = document.execCommand("insertText", false, text);
    } catch {
      done = false;
    }
    if (!done) {
      ta.setRangeText(text, start, end, "end");
      ta.dispatchEvent(new Event("input", { bubbles: true }));
    }
  }

  // ---- wiring -------------------------------------------------------------------------------
  function init(scope = document) {
    for (const root of scope.querySelectorAll("[data-editor]")) {
      if (root.classList.contains("editor--on") || !root.querySelector("textarea")) continue;
      editors.push(new Editor(root));
    }
  }

  function editorForList(el) {
    return editors.find((ed) => {
      const list = document.querySelector(ed.errorsSelector);
      return list && list.contains(el);
    });
  }

  const rereadLists = (event) => {
    if (event.type === "htmx:afterSettle") init(); // editors swapped in
    for (const ed of editors) if (ed.root.isConnected) ed.readErrorList();
  };
  document.addEventListener("htmx:afterSwap", rereadLists);
  document.addEventListener("htmx:afterSettle", rereadLists);

  document.addEventListener("click", (event) => {
    const li = event.target.closest?.("li[data-line]");
    const ed = li && editorForList(li);
    if (ed) ed.goTo(Number(li.dataset.line), Number(li.dataset.column) || 1);
  });
  document.addEventListener("keydown", (event) => {
    if (event.key !== "Enter" && event.key !== " ") return;
    const li = event.target.closest?.("li[data-line]");
    const ed = li && editorForList(li);
    if (!ed) return;
    event.preventDefault();
    ed.goTo(Number(li.dataset.line), Number(li.dataset.column) || 1);
  });

  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", () => init());
  else init();

  const current = () => editors.find((ed) => ed.root.isConnected);
  window.sequenceEditor = {
    markErrors(list) {
      current()?.markErrors(list);
    },
    goTo(line, column) {
      current()?.goTo(line, column);
    },
    /** after setting the textarea's value from script */
    refresh() {
      for (const ed of editors) if (ed.root.isConnected) ed.update();
    },
    highlightLine: (text) => highlightLine(text, START)[0],
  };
})();
