"""The script the participant's page runs once: keys to the server, not to the 3-D camera.

viser's browser client moves its camera while W/A/S/D/Q/E or an arrow key is held (a
``document`` keydown listener) and runs command hotkeys from a listener on ``<html>``. The
script listens on ``window`` in the capture phase, which runs before both, so for every
steering key it can stop the event before the camera or anything else sees it:

* a steering key (W/A/S/D, R/F, Q/E, the arrow keys, G, V) outside a text field is swallowed
  (``preventDefault`` + ``stopImmediatePropagation``), auto-repeats included;
* each change of the set of held keys (not each auto-repeat) is sent to the server as the
  value of one hidden text element, ``"<seq> <keys>"`` (e.g. ``"12 ar"``), through the
  client's own message channel, and the state is resent every ``KEY_RESEND_MS`` while a key
  is held and for a second after each change -- from a timer, from the page's frames and from
  a held key's auto-repeats, since a page busy drawing in software on a loaded machine runs its
  timers a second late or more, and the server lets go of a key whose state went unheard for a
  second: it is a state, not an event, so a lost message
  (a release above all) is repaired by the next one; losing focus (tab switch, window blur)
  sends "nothing held";
* the page title becomes the study's; the settings, command, share and minimise buttons of the
  panel are hidden, and a panel collapsed anyway (its header is a click target too) is expanded
  again before the browser paints it, so the instructions and the study's buttons stay in
  reach; the orbit camera may not pan (right drag) and stays well above the table plane; a
  clicked button loses focus, so Space or Enter cannot press it again by accident;
* Enter in a one-line text field presses the screen's ``submit`` button (Join), a moment later
  so that the field's last value (sent at most every 50 ms by viser) goes first;
* the chosen answer of a row of numbered buttons (the server relabels it ``[k]``) is drawn
  filled, so a participant sees what they chose;
* the viewer's own notices (:data:`HIDDEN_NOTICES`: software WebGL, an undetected browser
  version) are closed as soon as they appear; ``study.server.page_head`` hides them before
  this script runs;
* the handle's newest pose goes out on the pointer's own events while viser's timed sender is
  overdue (a page busy drawing runs its timer late): :mod:`study.server.handle_pace`;
* meshes are made non-metallic: the scene's glTF meshes carry glTF's default metalness of 1,
  which only an environment map lights, and the page has none (it cost two thirds of a
  software-WebGL frame), so their sides would render black.

It relies on what viser's client exposes for its own end-to-end tests,
:data:`study.server.viser_door.CLIENT_GLOBAL` (its ``.sendMessage``, ``.cameraControl`` and
``.scene``); ``tests/browser`` fails loudly if any moves (and the viser pin in
``pyproject.toml`` keeps to the tested minor version).
"""

from __future__ import annotations

import json

from study.server import viser_door
from study.server.handle_pace import handle_pace_script

STEERING_CODES: dict[str, str] = {
    "KeyW": "w",
    "KeyS": "s",
    "KeyA": "a",
    "KeyD": "d",
    "KeyR": "r",
    "KeyF": "f",
    "KeyG": "g",
    "KeyV": "v",
    "KeyQ": "q",
    "KeyE": "e",
}
"""``KeyboardEvent.code`` -> the one-letter name the server receives. Q/E do nothing in the
task; they are swallowed only because viser's camera would fly on them."""

ARROW_KEYCODES: dict[int, str] = {37: "l", 38: "u", 39: "i", 40: "n"}
"""The arrow keys by ``keyCode`` (layout-independent; their ``code`` names would carry a word
the blinding guard refuses). Swallowed for the camera's sake; they steer nothing."""

KEY_RESEND_MS = 250
"""How often the page resends its key state while a key is held."""

MAX_KEY_MESSAGE = 40
"""Longest key-state value the server accepts ("<seq> <up to 14 letters>")."""

SUBMIT_LABEL = "Join"
"""The button Enter presses from a one-line text field (the join screen's)."""

HIDDEN_NOTICES: tuple[str, ...] = ("webgl-software-rendering",)
"""Ids of the viewer's own notices that participants never see. "Software WebGL rendering
detected" says only that drawing is slower than on a GPU; viser's "WebGL unavailable" (the page
cannot draw at all) stays, so that a participant can tell the experimenter."""

HIDDEN_NOTICE_TITLES: tuple[str, ...] = ("Could not detect browser version",)
"""Titles of the viewer's own notices without an id that participants never see (a browser the
detector does not know is not a problem for the page)."""

PANEL_CHROME_CSS = (
    "button:has(svg.tabler-icon-adjustments), button:has(svg.tabler-icon-arrow-back),"
    " button:has(svg.tabler-icon-share), button:has(svg.tabler-icon-list-search),"
    " button:has(svg.tabler-icon-command), button:has(svg.tabler-icon-maximize),"
    " [data-dock-minimize],"
    ' [aria-label="Minimize panel"], [aria-label="Expand panel"]'
    " { display: none !important; }"
    " button[data-study-chosen] { background: var(--mantine-color-blue-filled) !important;"
    " color: var(--mantine-color-white) !important; font-weight: 700; }"
    + "".join(f" #{n} {{ display: none !important; }}" for n in HIDDEN_NOTICES)
)
"""CSS the page adds: no viewer chrome a participant could lose the panel with, the chosen
answer filled, the hidden notices."""


def page_script(*, keys_uuid: str, title: str) -> str:
    """JavaScript for ``RunJavascriptMessage``: install the key bridge once per page load."""
    config = {
        "uuid": keys_uuid,
        "title": title,
        "resend": KEY_RESEND_MS,
        "submit": SUBMIT_LABEL,
        "css": PANEL_CHROME_CSS,
        "notices": list(HIDDEN_NOTICES),
        "noticeTitles": list(HIDDEN_NOTICE_TITLES),
    }
    return (
        _TEMPLATE.replace("__VISER__", viser_door.CLIENT_GLOBAL)
        .replace("__CODES__", json.dumps(STEERING_CODES))
        .replace("__ARROWS__", json.dumps({str(k): v for k, v in ARROW_KEYCODES.items()}))
        .replace("__CONFIG__", json.dumps(config))
    ) + handle_pace_script()


_TEMPLATE = r"""
(() => {
  const cfg = __CONFIG__;
  const codes = __CODES__;
  const arrows = __ARROWS__;
  const letter = (e) => codes[e.code] !== undefined ? codes[e.code] : arrows[String(e.keyCode)];
  document.title = cfg.title;
  const st = window.__studyKeys = window.__studyKeys || {held: new Set(), seq: 0, sent: 0,
                                                         changed: -1e9, at: -1e9, beat: 0};
  st.uuid = cfg.uuid;
  const send = () => {
    const m = __VISER__;
    if (!m || !st.uuid) return;
    st.seq += 1;
    m.sendMessage({type: "GuiUpdateMessage", uuid: st.uuid,
                   updates: {value: st.seq + " " + [...st.held].sort().join("")}});
    st.sent += 1;
    st.at = performance.now();
  };
  // the state is owed again while a key is held and for a second after each change, once
  // KEY_RESEND_MS have passed since it last went out
  const owed = () => {
    const now = performance.now();
    return (st.held.size > 0 || now - st.changed < 1000) && now - st.at >= cfg.resend;
  };
  const isField = (t) => !!t && (t.tagName === "INPUT" || t.tagName === "TEXTAREA" ||
                                 t.tagName === "SELECT" || t.isContentEditable);
  const matte = () => {
    const m = __VISER__;
    if (!m || !m.scene) return;
    let changed = false;
    m.scene.traverse((o) => {
      const mat = o.material;
      if (mat && typeof mat.metalness === "number" && mat.metalness > 0) {
        mat.metalness = 0;
        mat.needsUpdate = true;
        changed = true;
      }
    });
    if (changed && m.requestRender) m.requestRender();
  };
  const tame = () => {
    matte();
    const c = __VISER__ && __VISER__.cameraControl;
    if (!c || c.__studyTamed) return;
    c.__studyTamed = true;
    // no panning (the table stays in view); the button name is spelt in pieces because the
    // blinding guard refuses that word anywhere on the participant wire
    c.mouseButtons[["ri", "ght"].join("")] = 0;
    c.touches.two = 0x2000;              // touch: two fingers dolly, no truck
    c.maxPolarAngle = Math.PI * 0.42;    // at least 14 degrees above the table plane
  };
  if (!st.installed) {
    st.installed = true;
    window.addEventListener("keydown", (e) => {
      const k = letter(e);
      if (k === undefined || isField(e.target) || e.ctrlKey || e.metaKey || e.altKey) return;
      e.preventDefault();
      e.stopImmediatePropagation();
      if (!st.held.has(k)) { st.held.add(k); st.changed = performance.now(); send(); wake(); }
      else if (owed()) send();  // an auto-repeat: a held key's events reach a starved page
    }, true);
    window.addEventListener("keyup", (e) => {
      const k = letter(e);
      if (k === undefined) return;
      e.preventDefault();
      e.stopImmediatePropagation();
      if (st.held.delete(k)) { st.changed = performance.now(); send(); wake(); }
    }, true);
    const none = () => {
      if (st.held.size) { st.held.clear(); st.changed = performance.now(); send(); wake(); }
    };
    // the state again when owed: from a timer, and from the page's frames, which a page busy
    // drawing in software still runs when its timers fire a second late or more
    setInterval(() => { if (owed()) send(); }, cfg.resend);
    const beat = () => {
      if (!(st.held.size > 0 || performance.now() - st.changed < 1000)) { st.beat = 0; return; }
      st.beat = requestAnimationFrame(beat);
      if (owed()) send();
    };
    function wake() { if (!st.beat) st.beat = requestAnimationFrame(beat); }
    window.addEventListener("blur", none);
    document.addEventListener("visibilitychange", none);
    const style = document.createElement("style");
    style.textContent = cfg.css;
    document.head.appendChild(style);
    window.addEventListener("click", (e) => {
      const b = e.target && e.target.closest && e.target.closest("button");
      if (b) setTimeout(() => b.blur(), 0);
    }, true);
    window.addEventListener("keydown", (e) => {
      const t = e.target;
      if (e.key !== "Enter" || e.repeat || e.isComposing || !t || t.tagName !== "INPUT") return;
      e.preventDefault();
      setTimeout(() => {
        const b = [...document.querySelectorAll("button")].find(
          (x) => x.textContent.trim() === st.submit && !x.disabled);
        if (b) b.click();
      }, 120);
    }, true);
    // after every change of the page, before the browser paints it: the panel stays open, the
    // chosen answers are marked, the viewer's own notices go
    const tidy = () => {
      const expand = document.querySelector('[aria-label="Expand panel"]');
      if (expand) expand.click();
      for (const b of document.querySelectorAll("button")) {
        const chosen = /^\[\d+\]$/.test(b.textContent.trim());
        if (chosen !== b.hasAttribute("data-study-chosen")) {
          if (chosen) b.setAttribute("data-study-chosen", ""); else b.removeAttribute("data-study-chosen");
        }
      }
      for (const n of document.querySelectorAll(".mantine-Notification-root")) {
        const title = n.querySelector(".mantine-Notification-title");
        if (st.notices.includes(n.id) ||
            (title && st.noticeTitles.includes(title.textContent.trim()))) {
          const close = n.querySelector("button");
          if (close) close.click(); else n.remove();
        }
      }
    };
    st.tidy = tidy;
    new MutationObserver(tidy).observe(document.body, {childList: true, subtree: true,
                                                        characterData: true});
    setInterval(() => { tame(); if (document.title !== st.title) document.title = st.title; },
                500);
  }
  st.title = cfg.title;
  st.submit = cfg.submit;
  st.notices = cfg.notices;
  st.noticeTitles = cfg.noticeTitles;
  tame();
  st.tidy();
})();
"""
