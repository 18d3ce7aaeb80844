"""The participant-facing part of a protocol: questionnaire, texts, and the blinding check.

Everything here reaches the participant's browser, so :func:`check_blinding` rejects any text
containing a word of the protocol's blinded vocabulary (:mod:`study.protocol.blinding`: a level
of any factor, a task or mode name, or one of the fixed words; as a word or inside one: "bright"
holds "right"), the same words the study server's wire guard blocks for this protocol.
"""

from __future__ import annotations

import re
import string
from types import MappingProxyType

from study.protocol.blinding import find_words
from study.protocol.errors import BlindingError, ScaleMismatchError, UndefinedReferenceError
from study.protocol.fields import Table, join_key
from study.protocol.model import Texts
from study.protocol.protocol import Protocol
from study.protocol.questionnaire import PHASES, LikertItem, Questionnaire, Scale

INSTRUCTIONS_REQUIRED = ("welcome", "training", "task", "rating")
INSTRUCTIONS_OPTIONAL = ("preference", "pause")  # preference: required if after_task is asked
PLACEHOLDERS = {"training": {"target"}, "task": {"target"}}
_ITEM_ID = re.compile(r"^[a-z][a-z0-9_]{0,31}$")
_COMPLETION_CODE = re.compile(r"[A-Za-z0-9_-]{1,64}", re.ASCII)
_URL = re.compile(r"https?://[^\s\\\"'<>`]{1,2000}", re.ASCII)
REDIRECT_PLACEHOLDERS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID", "pid")
"""What ``debrief.redirect_url`` may contain in braces: the participant's browser fills each in
from its own link (``study.server.recruitment``)."""


def read_questionnaire(t: Table, *, n_modes: int) -> Questionnaire:
    """``[questionnaire]``: points, scales (one anchor per point), items, when each is asked."""
    t.only("points", "scales", "items", *PHASES)
    points = t.integer("points", minimum=2, maximum=11)
    scales: dict[str, Scale] = {}
    for name, sub in t.table("scales").tables():
        sub.only("anchors")
        anchors = sub.strings("anchors", unique=True)
        if len(anchors) != points:
            raise ScaleMismatchError(
                f"{len(anchors)} anchors for a {points}-point questionnaire"
                f" (questionnaire.points = {points}); give one anchor per point",
                file=t.file,
                key=sub.where("anchors"),
            )
        scales[name] = Scale(name=name, anchors=anchors)
    items: dict[str, LikertItem] = {}
    items_table = t.table("items")
    for item_id, sub in items_table.tables():
        if not _ITEM_ID.match(item_id):
            raise items_table.value_error(
                item_id, "item ids name data columns: lower-case letters, digits and '_'"
            )
        sub.only("prompt", "scale")
        scale_name = sub.string("scale")
        if scale_name not in scales:
            raise UndefinedReferenceError(
                f"scale {scale_name!r} is not defined in questionnaire.scales"
                f" ({', '.join(scales) or 'none'})",
                file=t.file,
                key=sub.where("scale"),
            )
        items[item_id] = LikertItem(
            id=item_id, prompt=sub.string("prompt"), scale=scales[scale_name]
        )
    asked: dict[str, tuple[LikertItem, ...]] = {}
    for phase in PHASES:
        ids = t.strings(phase, [], nonempty=False)
        for i, item_id in enumerate(ids):
            if item_id not in items:
                raise UndefinedReferenceError(
                    f"item {item_id!r} is not defined in questionnaire.items",
                    file=t.file,
                    key=join_key(t.where(phase), i),
                )
        asked[phase] = tuple(items[i] for i in ids)
    if asked["after_task"] and n_modes != 2:
        raise t.value_error(
            "after_task",
            f"a preference between a task's two runs needs exactly 2 modes, this protocol has"
            f" {n_modes}; leave after_task empty",
        )
    return Questionnaire(points=points, items=MappingProxyType(items), **asked)


def read_texts(root: Table, *, questionnaire: Questionnaire) -> Texts:
    """``[consent]`` (text, agree), ``[debrief]`` (text) and ``[instructions]`` per phase."""
    consent = root.table("consent")
    consent.only("text", "agree")
    debrief = root.table("debrief")
    debrief.only("text", "completion_code", "redirect_url")
    t = root.table("instructions")
    t.only(*INSTRUCTIONS_REQUIRED, *INSTRUCTIONS_OPTIONAL)
    instructions: dict[str, str] = {}
    for phase in INSTRUCTIONS_REQUIRED + INSTRUCTIONS_OPTIONAL:
        required = phase in INSTRUCTIONS_REQUIRED or (
            phase == "preference" and bool(questionnaire.after_task)
        )
        if required or phase in t:
            instructions[phase] = _placeholders_checked(t, phase)
    return Texts(
        consent=consent.string("text"),
        consent_agree=consent.string("agree"),
        debrief=debrief.string("text"),
        instructions=MappingProxyType(instructions),
        completion_code=_completion_code(debrief),
        redirect_url=_redirect_url(debrief),
    )


def _completion_code(t: Table) -> str:
    """``debrief.completion_code``: what an online panel asks participants to paste back."""
    if "completion_code" not in t:
        return ""
    code = t.string("completion_code")
    if not _COMPLETION_CODE.fullmatch(code):
        raise t.value_error("completion_code", "use 1-64 letters, digits, '-' or '_'")
    return code


def _redirect_url(t: Table) -> str:
    """``debrief.redirect_url``: an http(s) URL, its only placeholders the link's IDs."""
    if "redirect_url" not in t:
        return ""
    url = t.string("redirect_url")
    if not _URL.fullmatch(url):
        raise t.value_error(
            "redirect_url", "give an http:// or https:// URL without spaces or quotes"
        )
    fields = re.findall(r"\{([^{}]*)\}", url)
    unknown = [f for f in fields if f not in REDIRECT_PLACEHOLDERS]
    if unknown or url.count("{") != len(fields) or url.count("}") != len(fields):
        allowed = ", ".join(f"{{{p}}}" for p in REDIRECT_PLACEHOLDERS)
        raise t.value_error("redirect_url", f"placeholders may only be {allowed}")
    return url


def _placeholders_checked(t: Table, phase: str) -> str:
    text = t.string(phase)
    allowed = PLACEHOLDERS.get(phase, set())
    try:
        fields = [f for _, f, _, _ in string.Formatter().parse(text) if f is not None]
    except ValueError as e:
        raise t.value_error(
            phase, f"bad braces ({e}); write {{{{ and }}}} for literal braces"
        ) from None
    for f in fields:
        if f not in allowed:
            hint = f"allowed: {{{', '.join(sorted(allowed))}}}" if allowed else "none allowed"
            raise t.value_error(phase, f"unknown placeholder {{{f}}} ({hint})")
    return text


def participant_texts(p: Protocol) -> list[tuple[str, str]]:
    """Every (key path, text) of ``p`` that a participant may see."""
    texts = [
        ("consent.text", p.texts.consent),
        ("consent.agree", p.texts.consent_agree),
        ("debrief.text", p.texts.debrief),
        ("debrief.completion_code", p.texts.completion_code),
        ("debrief.redirect_url", p.texts.redirect_url),
    ]
    texts += [(f"instructions.{k}", v) for k, v in p.texts.instructions.items()]
    scales = {}
    for item in p.questionnaire.items.values():
        texts.append((f"questionnaire.items.{item.id}.prompt", item.prompt))
        scales[item.scale.name] = item.scale
    for scale in scales.values():
        texts += [
            (f"questionnaire.scales.{scale.name}.anchors[{i}]", a)
            for i, a in enumerate(scale.anchors)
        ]
    for name, scene in p.scenes.items():  # object names label the participant's 3-D scene
        texts += [(f"scenes.{name}.objects[{i}].name", o) for i, o in enumerate(scene.object_names)]
    for task in p.tasks:
        texts.append((f"scenes.{task.scene}.target", p.describe_trial(task.name)))
    texts.append((f"scenes.{p.training.scene}.target", p.describe_training()))
    return texts


def check_blinding(p: Protocol) -> None:
    """Raise :class:`BlindingError` at the first participant-facing text naming a condition."""
    words = p.condition_words
    for key, text in participant_texts(p):
        found = find_words(text, words)
        if found:
            fix = (
                "choose a neutral object name (e.g. 'bottle')"
                if key.endswith(".name")
                else f"rephrase: {text[:60]!r}"
            )
            raise BlindingError(
                f"participant-facing text contains the condition word(s) {found} (as a word or"
                f" inside one, e.g. 'bright' holds 'right'); {fix}",
                file=p.path,
                key=key,
            )
