"""What a response's structure says beyond its words: the chosen and the rejected reaction, quoted words,
who is addressed, and whether the text is a log line, background talk or a model that did not understand.

:func:`analyse` returns character spans and a few cue flags for one text, read by plain rules (no model):

- **rejected spans**: a reaction named and turned down: from a negation or contrast marker ("not", "don't",
  "rather than", "instead of", "no need to", "avoid", "resist the urge to", "tempting to ... but") to the end
  of its clause (a comma, semicolon, dash, colon, full stop, "but", "just", "instead");
- **chosen spans**: everything else (the whole text when nothing was rejected);
- **quoted spans**: text between matching quotation marks;
- **flags** (:data:`FLAGS`): cues of words addressed to someone else, reported or quoted speech, system and log
  lines, background talk (TV, radio, phone), a reasoner that did not understand, questions.

The encoder pools its token states over each span (one forward pass; :func:`jgrounding.semantics.encoder.pool_ids`),
so the trained head sees the chosen reaction, the rejected one and the quoted words apart, and the flags tell it
what kind of text it reads. The head learns what to make of them; nothing here decides an intent.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np

# A clause ends at punctuation or where a contrast turns to the chosen reaction.
_BOUNDARY = re.compile(
    r"[,;:.!?\u2014\u2013()\n]|\s-\s|\s--\s|\b(?:but|just|instead|rather|only|and then|so|because|while)\b",
    re.IGNORECASE,
)
# Markers that start a rejected reaction (the rejected span runs from the marker to its clause's end).
_REJECT = re.compile(
    r"\b(?:rather than|instead of|as opposed to|in place of|no need to|there'?s no need (?:to|for)|"
    r"don'?t|do not|doesn'?t|does not|shouldn'?t|should not|won'?t|will not|wouldn'?t|mustn'?t|must not|"
    r"never|avoid(?:ing)?|without|not|no|nothing like|skip(?:ping)? the|hold off on|resist(?:ing)? the urge to|"
    r"(?:it'?s |it is |it would be )?tempting to|(?:you )?might (?:want|be tempted) to|less|forget (?:the|about)|"
    r"(?:is|would be|seems?) (?:too much|overkill|wrong|inappropriate|out of place))\b",
    re.IGNORECASE,
)
# Markers after which the rejection ends at "but" (the tempting reaction is named, then turned down).
_TEMPTING = re.compile(r"tempting|might|urge", re.IGNORECASE)
_QUOTE_PAIRS = (('"', '"'), ("\u201c", "\u201d"), ("\u2018", "\u2019"), ("'", "'"), ("\u00ab", "\u00bb"))
_NOT_NAMES = {
    "yes", "no", "okay", "ok", "well", "now", "please", "sure", "alright", "right", "so", "oh", "hmm", "plan",
    "observation", "user", "trunk", "then", "again", "also", "next", "first", "sorry", "thanks", "great", "good",
    "fine", "wow", "hey", "hi", "hello", "look", "listen", "careful", "gently", "slowly", "quick", "quickly",
    "easy", "honestly", "actually", "anyway", "clearly", "calmly", "softly", "finally", "motion", "reason",
    "reasoning", "response", "action", "context", "situation", "note", "intent", "intensity", "here", "there",
}  # fmt: skip
_VOCATIVE = re.compile(r"^\W*(?:(?:hey|hi|ok|okay|oi|yo|so|and)\s+)?([A-Z][a-z]+|mom|mum|dad)\s*[,:!]", re.IGNORECASE)
_TRAILING_VOCATIVE = re.compile(r",\s*([A-Z][a-z]+)\s*[?.!]*\s*$")
_OTHER_PERSON = re.compile(
    r"\b(?:tell|ask|remind|let|get|have)\s+(?:[A-Z][a-z]+|him|her|your (?:\w+)|my (?:\w+)|the (?:kids?|children|"
    r"guests?|waiter|nurse|staff|team|driver|neighbou?r))\s+(?:to|that|know|we)\b|@\w+|\b(?:to|for) the (?:kids?|"
    r"nurse|staff|waiter|team)\b"
)
_REPORTED = re.compile(
    r"\b(?:said|says|say(?:ing)?|asked|asks|told|tells|yelled|yells|shouted|shouts|whispered|whispers|writes|wrote|"
    r"goes|went|muttered|mutters|replied|replies|announced|announces|quote|quoting|read(?:s)? out)\b",
    re.IGNORECASE,
)
_LOG = re.compile(
    r"\b\d{1,2}:\d{2}(?::\d{2})?\b|\b\d{4}-\d{2}-\d{2}\b|^\s*\[[^\]]{1,40}\]|\b(?:INFO|WARN|WARNING|ERROR|DEBUG|TRACE|"
    r"FATAL|CRITICAL|OK|ACK|NACK)\b|\b\w+=\S+|\b\w+\.\w+\(|0x[0-9a-fA-F]+|\b(?:exit code|status code|errno|"
    r"stack ?trace|traceback|exception|pid|heartbeat|battery|firmware|reboot(?:ing)?|timeout|latency|checksum|"
    r"uptime|cpu|gpu|ram|ms|kb|mb|gb|hz|v\d+(?:\.\d+)+)\b|\b[a-z]+_[a-z_]+\b|[{}<>|\\/]{1}",
)
_SYSTEM = re.compile(
    r"^\W*(?:system|sys|assistant|log|logger|debug|status|server|kernel|daemon|bot|api)\s*[:>\]\-]", re.I
)
_NOT_UNDERSTOOD = re.compile(
    r"\b(?:didn'?t|did not|couldn'?t|could not|can'?t|cannot|don'?t|do not|am not able to|unable to)\s+"
    r"(?:quite\s+|really\s+|fully\s+)?(?:understand|catch|hear|follow|parse|make out|tell|interpret|work out|read)|"
    r"\b(?:unclear|not sure what|repeat that|say that again|inaudible|garbled|unintelligible|no idea what|"
    r"not clear|too noisy|cut out|couldn'?t make sense|makes? no sense|ambiguous|pardon)\b",
    re.IGNORECASE,
)
_BACKGROUND = re.compile(
    r"\b(?:tv|television|radio|podcast|video|movie|film|show|series|episode|announcer|commercial|advert\w*|"
    r"news(?:reader)?|broadcast|loudspeaker|speaker|background|next room|overheard|on the phone|phone call|"
    r"someone else|another person|other people|neighbou?rs?|the couple|two people|a stranger|passers?-?by)\b",
    re.IGNORECASE,
)
_QUESTION_START = re.compile(
    r"^\W*(?:what|why|how|when|where|who|which|is|are|do|does|did|can|could|would|will|should|have|has)\b", re.I
)
_FIRST_PERSON = re.compile(r"\b(?:I|I'm|I'll|I've|me|my|we|we're|us|our)\b")
_TRUNK = re.compile(r"\b(?:trunk|tip|coil|tendon|respond|react|motion|gesture|move|movement)\w*", re.IGNORECASE)

FLAGS = (
    "has_rejected",
    "rejected_share",
    "quoted_share",
    "starts_with_quote",
    "reported_speech",
    "vocative",
    "other_person",
    "log_line",
    "system_prefix",
    "not_understood",
    "background",
    "question_mark",
    "question_start",
    "first_person",
    "names_trunk",
    "sentences",
    "digits_share",
    "symbol_share",
)
NUM_FLAGS = len(FLAGS)


@dataclasses.dataclass(frozen=True)
class Structure:
    """Spans (``(start, end)`` character ranges) and cue flags ``(NUM_FLAGS,)`` of one text."""

    rejected: tuple
    quoted: tuple
    flags: np.ndarray

    def chosen_text(self, text: str) -> str:
        """The text with its rejected spans cut out (the whole text when nothing was rejected)."""
        out, last = [], 0
        for a, b in self.rejected:
            out.append(text[last:a])
            last = b
        out.append(text[last:])
        chosen = " ".join(s.strip() for s in out if s.strip())
        return chosen if re.search(r"[A-Za-z]{2,}", chosen) else text

    def rejected_text(self, text: str) -> str:
        return " ; ".join(text[a:b] for a, b in self.rejected)


def _rejected_spans(text: str) -> list[tuple[int, int]]:
    spans = []
    for m in _REJECT.finditer(text):
        if spans and m.start() < spans[-1][1]:
            continue
        start = m.start()
        stop_at_but = bool(_TEMPTING.search(m.group(0)))
        pos = m.end()
        end = len(text)
        for b in _BOUNDARY.finditer(text, pos):
            if b.start() == pos and not b.group(0).strip(" ").isalpha():
                continue
            word = b.group(0).strip().lower()
            if stop_at_but and word not in ("but", ".", ";", "!", "?", "\u2014", "\u2013", "\n"):
                continue
            end = b.start()
            break
        if end - start > 0:
            spans.append((start, end))
    return spans


def _quote_pattern(open_q: str, close_q: str) -> re.Pattern:
    if open_q == "'":  # apostrophes: a quote opens after a space or start and closes before one or the end
        return re.compile(r"(?:(?<=^)|(?<=[\s(:]))'([^']{2,}?)'(?=$|[\s.,;:!?)])")
    return re.compile(re.escape(open_q) + r"([^" + re.escape(open_q + close_q) + r"]{1,}?)" + re.escape(close_q))


_QUOTE_RE = tuple((open_q, _quote_pattern(open_q, close_q)) for open_q, close_q in _QUOTE_PAIRS)


def _quoted_spans(text: str) -> list[tuple[int, int]]:
    spans = []
    for open_q, pattern in _QUOTE_RE:
        if open_q not in text:  # no opening mark, no quote of this kind
            continue
        for m in pattern.finditer(text):
            if not any(a <= m.start() < b for a, b in spans):
                spans.append((m.start(1), m.end(1)))
    return sorted(spans)


def spans(text: str) -> Structure:
    """The rejected and quoted spans of one text without its flags (``flags`` empty): what the no-motion rule
    (:mod:`jgrounding.semantics.nomotion`) reads, at a sixth of :func:`analyse`'s cost."""
    return Structure(tuple(_rejected_spans(text)), tuple(_quoted_spans(text)), np.zeros(0, np.float32))


def analyse(text: str) -> Structure:
    """Spans and flags of one text (plain rules, microseconds)."""
    rejected = _rejected_spans(text)
    quoted = _quoted_spans(text)
    n = max(len(text), 1)
    letters = re.sub(r"\s", "", text)
    m = max(len(letters), 1)
    stripped = text.strip().rstrip("\"'\u201d\u2019)")
    vocative = _VOCATIVE.match(text)
    trailing = _TRAILING_VOCATIVE.search(text)
    has_vocative = bool(
        (vocative and vocative.group(1).lower() not in _NOT_NAMES)
        or (trailing and trailing.group(1).lower() not in _NOT_NAMES)
    )
    flags = [
        float(bool(rejected)),
        sum(b - a for a, b in rejected) / n,
        sum(b - a for a, b in quoted) / n,
        float(bool(re.match(r"^\W{0,3}[\"\u201c\u2018']", text.strip()))),
        float(bool(_REPORTED.search(text))),
        float(has_vocative),
        float(bool(_OTHER_PERSON.search(text))),
        min(len(_LOG.findall(text)), 4) / 4,
        float(bool(_SYSTEM.match(text))),
        float(bool(_NOT_UNDERSTOOD.search(text))),
        float(bool(_BACKGROUND.search(text))),
        float(stripped.endswith("?")),
        float(bool(_QUESTION_START.match(text))),
        float(bool(_FIRST_PERSON.search(text))),
        float(bool(_TRUNK.search(text))),
        min(len(re.findall(r"[.!?]+(?:\s|$)", text)), 5) / 5,
        sum(c.isdigit() for c in letters) / m,
        sum(not c.isalnum() and c not in ".,;:!?'\"-" for c in letters) / m,
    ]
    return Structure(tuple(rejected), tuple(quoted), np.array(flags, np.float32))
