"""The console's texts: the records of ``study.server.console_model`` as markdown."""

from __future__ import annotations

from collections.abc import Sequence

from study.server.console_model import LinkState, SessionDetail, SessionSummary, StudyProgress


def fmt_time(seconds: float | None) -> str:
    if seconds is None:
        return "not started"
    m, s = divmod(max(0.0, seconds), 60.0)
    h, m = divmod(int(m), 60)
    return f"{h}:{m:02d}:{s:04.1f}" if h else f"{m:02d}:{s:04.1f}"


def sessions_markdown(rows: Sequence[SessionSummary]) -> str:
    if not rows:
        return "_No sessions yet. Enrol a participant to start one._"
    lines = [
        "| code | participant | state | step | tab | session time |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        tab = "connected" if r.connected else "-"
        who = r.participant + (" (link)" if r.source == "link" else "")
        lines.append(
            f"| `{r.code}` | {who} | {r.state} | {r.position} | {tab} | {fmt_time(r.elapsed_s)} |"
        )
    return "\n".join(lines)


def schedule_markdown(detail: SessionDetail) -> str:
    lines = ["| # | step | task | mode |", "|---|---|---|---|"]
    for k, (label, task, mode) in enumerate(detail.schedule):
        mark = "**>**" if k == detail.cursor else ""
        lines.append(f"| {mark} {k + 1} | {label} | {task} | {mode} |")
    return "\n".join(lines)


def trials_markdown(detail: SessionDetail) -> str:
    """Every attempt of the session so far, with how it ended."""
    if not detail.trials:
        return "_No runs yet._"
    lines = ["| run | attempt | status | outcome | time |", "|---|---|---|---|---|"]
    for label, attempt, status, outcome, duration in detail.trials:
        lines.append(f"| {label} | {attempt} | {status} | {outcome} | {duration} |")
    return "\n".join(lines)


TIMELINE_ROWS = 40
"""Timeline entries shown (the newest); the store keeps them all."""


def timeline_markdown(detail: SessionDetail) -> str:
    """The session's runs and events, newest first, under a one-line tally."""
    head = f"**Timeline** ({detail.tally})" if detail.tally else "**Timeline**"
    if not detail.timeline:
        return head + "\n\n_Nothing yet._"
    rows = list(reversed(detail.timeline))
    lines = [head, "", "| time | session | what |", "|---|---|---|"]
    lines += [f"| {at} | {since} | {what} |" for at, since, what in rows[:TIMELINE_ROWS]]
    if len(rows) > TIMELINE_ROWS:
        lines.append(f"| | | _{len(rows) - TIMELINE_ROWS} earlier entries (in the store)_ |")
    return "\n".join(lines)


def progress_markdown(p: StudyProgress) -> str:
    planned = f" of **{p.planned}** planned" if p.planned else " (no planned number)"
    lines = [
        f"Participants completed: **{p.completed}**{planned}; in progress {p.running};"
        f" withdrawn or ended {p.stopped}"
    ]
    if p.conditions:
        lines += ["", "| condition | runs | success |", "|---|---|---|"]
        for label, n, ok in p.conditions:
            rate = f"{ok}/{n} ({100 * ok / n:.0f}%)" if n else "-"
            lines.append(f"| {label} | {n} | {rate} |")
    if p.next_schedule:
        lines += [
            "",
            f"Next participant: schedule row **{p.next_row}**: " + "; ".join(p.next_schedule),
        ]
    return "\n".join(lines)


def link_markdown(link: LinkState) -> str:
    if not link.enabled:
        return "Open link is **off**: participants need a join code."
    free = max(0, link.cap - link.used)
    why = {
        "off": "while it was off",
        "full": "while it was full",
        "address": "from an address past its new IDs for the hour",
    }
    refused = ", ".join(f"{n} {why.get(k, k)}" for k, n in link.refused if n)
    return (
        f"Open link is **on**: {link.used} of {link.cap} places taken ({free} free)."
        + (f" New IDs refused: {refused}." if refused else "")
        + f"\n\nLink for the recruitment site:\n\n`{link.url}`"
    )


def status_markdown(detail: SessionDetail) -> str:
    s = detail.summary
    lines = [
        f"**{s.participant}** (code `{s.code}`), state **{s.state}**"
        f"{' (paused)' if detail.paused else ''}; step {s.position}",
        f"Condition: **{detail.condition}**",
        f"Session time {fmt_time(s.elapsed_s)}, trial time"
        f" {fmt_time(detail.trial_elapsed_s) if detail.trial_elapsed_s else '-'};"
        f" participant tab {'connected' if s.connected else 'not connected'}",
    ]
    if detail.recruitment:
        lines.append("Recruitment: " + ", ".join(f"{k} `{v}`" for k, v in detail.recruitment))
    if detail.fault:
        lines.append(
            f"**Control error, trial paused:** `{detail.fault}`. Resume to try again;"
            " redo or end if it comes back."
        )
    return "\n\n".join(lines)
