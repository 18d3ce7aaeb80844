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
from study.protocol.errors import BlindingError
from study.protocol.fields import Table
from study.protocol.model import Texts
from study.protocol.protocol import Protocol
from study.protocol.questionnaire import ChoiceItem, Item, LikertItem, NumberItem, Questionnaire

INSTRUCTIONS_REQUIRED = ("welcome", "training", "task", "rating")
INSTRUCTIONS_OPTIONAL = (
    "preference",
    "pause",
    "after_training",
    "before_training",
    "between_tasks",
    "closing",
)
"""``preference`` is required if after_task items are asked; each questionnaire moment asked
once per participant (``before_training``, ``between_tasks``, ``closing``) needs its own
introduction when it has items; ``after_training`` introduces the items asked after the
practice runs (without it, a neutral sentence about the practice runs)."""
PLACEHOLDERS = {"training": {"target"}, "task": {"target"}, "preference": {"first", "last"}}
"""The placeholders each instruction may hold: ``{target}``, the target object's name;
``{first}`` and ``{last}``, the numbers ("Run 3 of 8": 3) of the first and last run the
preference compares, as the participant counted them."""
_COMPLETION_CODE = re.compile(r"[A-Za-z0-9_-]{1,64}", re.ASCII)
_URL = re.compile(r"https?://[^\s\\\"'<>`]{1,2000}", re.ASCII)
REDIRECT_PLACEHOLDERS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID", "pid")
"""What ``debrief.redirect_url`` may contain in braces: the participant's browser fills each in
from its own link (``study.server.recruitment``)."""


def read_texts(root: Table, *, questionnaire: Questionnaire) -> Texts:
    """``[consent]`` (text, agree, online_text), ``[debrief]`` (text, online_text, completion
    code, redirect) and ``[instructions]`` per phase. ``online_text``: what a participant who
    came by the open link reads instead of ``text`` (without it, ``text``)."""
    consent = root.table("consent")
    consent.only("text", "agree", "online_text")
    debrief = root.table("debrief")
    debrief.only("text", "online_text", "completion_code", "redirect_url")
    t = root.table("instructions")
    t.only(*INSTRUCTIONS_REQUIRED, *INSTRUCTIONS_OPTIONAL)
    instructions: dict[str, str] = {}
    for phase in INSTRUCTIONS_REQUIRED + INSTRUCTIONS_OPTIONAL:
        asks = {
            "preference": questionnaire.after_task,
            "before_training": questionnaire.before_training,
            "between_tasks": questionnaire.between_tasks,
            "closing": questionnaire.closing,
        }
        required = phase in INSTRUCTIONS_REQUIRED or bool(asks.get(phase))
        if required or phase in t:
            instructions[phase] = _placeholders_checked(t, phase)
    return Texts(
        consent=consent.string("text"),
        consent_agree=consent.string("agree"),
        debrief=debrief.string("text"),
        instructions=MappingProxyType(instructions),
        completion_code=_completion_code(debrief),
        redirect_url=_redirect_url(debrief),
        consent_online=consent.string("online_text") if "online_text" in consent else "",
        debrief_online=debrief.string("online_text") if "online_text" in debrief else "",
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
        ("consent.online_text", p.texts.consent_online),
        ("debrief.text", p.texts.debrief),
        ("debrief.online_text", p.texts.debrief_online),
        ("debrief.completion_code", p.texts.completion_code),
        ("debrief.redirect_url", p.texts.redirect_url),
    ]
    texts += [(f"instructions.{k}", v) for k, v in p.texts.instructions.items()]
    scales = {}
    for item in p.questionnaire.items.values():
        texts += item_texts(item)
        if isinstance(item, LikertItem):
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


def item_texts(item: Item) -> list[tuple[str, str]]:
    """(key path, text) of everything a participant reads of one item (its scale aside)."""
    key = f"questionnaire.items.{item.id}"
    texts = [(f"{key}.prompt", item.prompt)]
    if isinstance(item, ChoiceItem):
        texts += [(f"{key}.options[{i}]", o) for i, o in enumerate(item.options)]
    if isinstance(item, NumberItem) and item.unit:
        texts.append((f"{key}.unit", item.unit))
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
