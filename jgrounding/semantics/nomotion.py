"""The explicit no-motion decision: a rule over a text's structure and a learned detector that say *hold*
and why.

The trained head scores "no behaviour" as one class among 17, so a text that names the motion it rules out
("a hug isn't appropriate here; nothing for the trunk to do") can still come back as that motion, confident.
The rule (:func:`rule`) reads the text's structure instead (plain rules, microseconds, no second encoder pass)
and returns a :class:`Hold` (its kind and a reason for a person) when

- **rules_out**: the text rules the motion out ("no need to nod", "leave it", "nothing for the trunk to do");
- **freeze_order**: it orders the trunk to keep still ("freeze", "do not move", "hold position", "stay put");
- **addressed_other**: the words are meant for someone else (a call, voicemail, "X to Y: '...'", "not the robot");
- **observed_activity**: it only describes activity that asks nothing of the robot ("goes back to typing");
- **not_now**: it says to wait, or there is nobody to respond to ("wait until she wakes", "not yet");
- **handling**: the trunk is being handled or serviced ("calibration mode", "clamped in the test rig").

The motion words inside what is ruled out (rejected spans of :mod:`jgrounding.semantics.structure`, quoted
words, hypothetical or negated clauses) cannot override the hold: only a motion *chosen* outside them does
(:func:`chosen_motion`: an order, "the trunk should ...", "a tiny nod is enough", "big hug, full curl"), so
contrast texts ("don't X; just Y", "instead of X, Y", "skip the X and Y") still act on Y.

The rule's phrases were written against the training texts and miss unseen wording, so a **learned** detector
(:class:`Detector`) works beside it: a small MLP over the text's sentence vector, the one the shipped head's
program computes anyway (:func:`jgrounding.semantics.embedded.ground_embedded_vectors`), holds a text the rule
lets through when it is confident the text calls for no motion (kind ``learned``: "the text calls for no motion
(learned detector, p = 0.93)"), under the same :func:`chosen_motion` guard. It is trained on the training splits of the
blind-written no-motion sets and the head's motion texts (``python -m tools.train_nomotion`` writes
``jgrounding/assets/nomotion_detector.npz``), its threshold chosen by cross-validation so that it holds at most
1 % of each source's motion texts; it adds tens of microseconds to a grounding. A detector made for another head
(its vectors are that head's) is ignored, with a warning, until the tool is run again. Backends that do not run
the head (``cues``, ``mllm``) pay one encoder pass for the vector, only for texts the rule lets through.

:func:`check` is the decision (rule, then detector), :func:`apply` turns a grounding into a held one; the act/hold
decision (:func:`jgrounding.semantics.decision.decide`, which :func:`jgrounding.semantics.ground` calls for every
backend) applies it first, with the detector at the operating point's threshold, so the Responder, the CLI, the
server and its stream all get the same decision.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
from pathlib import Path

import numpy as np

from jgrounding.io import asset
from jgrounding.semantics import structure
from jgrounding.semantics.cues import DEGREE
from jgrounding.semantics.types import Grounding

LEARNED = "learned"  # the kind of a hold the learned detector made
DETECTOR_ASSET = asset("nomotion_detector.npz")

REASONS = {
    "rules_out": "the text rules the motion out",
    "freeze_order": "the text orders the trunk to keep still",
    "addressed_other": "the words are addressed to or meant for someone else",
    "observed_activity": "the text only describes activity that asks nothing of the robot",
    "not_now": "the text says to wait: nothing for the trunk to do yet",
    "handling": "the trunk is being handled or serviced",
    LEARNED: "the text calls for no motion",
}


@dataclasses.dataclass(frozen=True)
class Hold:
    """A no-motion decision: its kind (a key of :data:`REASONS`), the words that made it (for the learned
    detector: its probability) and the reason."""

    kind: str
    evidence: str
    p: float = 1.0  # how sure the decision is that the text calls for no motion (the rule: 1; the detector: its p)

    @property
    def reason(self) -> str:
        return f"{REASONS[self.kind]} ({self.evidence if self.kind == LEARNED else repr(self.evidence)})"


@dataclasses.dataclass(frozen=True)
class Detector:
    """The learned no-motion detector: p(no motion | sentence vector) of a one-hidden-layer MLP (GELU) over the
    standardized sentence vector; it holds at ``p >= threshold``. ``meta`` records what it was trained on."""

    arrays: dict  # mean, scale (384,); w1 (384, H), b1 (H,); w2 (H, 1), b2 (1,)
    threshold: float
    meta: dict

    def probability(self, vectors) -> np.ndarray:
        """Args: vectors ``(N, 384)`` (:func:`sentence_vectors`). Returns p(no motion) ``(N,)``, in numpy."""
        a = self.arrays
        z = (np.asarray(vectors, np.float32) - a["mean"]) / a["scale"]
        return _sigmoid(_gelu(z @ a["w1"] + a["b1"]) @ a["w2"] + a["b2"])[:, 0]


def _gelu(x):
    """GELU, tanh form (``jax.nn.gelu``'s default), so the detector trained in JAX runs here in numpy."""
    return 0.5 * x * (1.0 + np.tanh(np.float32(np.sqrt(2.0 / np.pi)) * (x + np.float32(0.044715) * x**3)))


def _sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def save_detector(path, arrays: dict, threshold: float, meta: dict) -> Path:
    """Write a detector atomically (float32 arrays, the threshold and ``meta`` as sorted JSON): the same
    arguments give the same bytes."""
    import io

    from jgrounding.io import write_atomic

    buf = io.BytesIO()
    arrays = {k: np.asarray(v, np.float32) for k, v in arrays.items()}
    np.savez(buf, **arrays, threshold=np.float64(threshold), meta=json.dumps(meta, sort_keys=True))
    return write_atomic(path, buf.getvalue())


def read_detector(path=None) -> Detector:
    """The detector stored at ``path`` (default: the shipped one); ``FileNotFoundError`` says how to make it."""
    path = Path(path or DETECTOR_ASSET)
    if not path.exists():
        raise FileNotFoundError(f"{path} missing; regenerate it with `python -m tools.train_nomotion`")
    with np.load(path) as f:
        arrays = {k: f[k] for k in ("mean", "scale", "w1", "b1", "w2", "b2")}
        return Detector(arrays, float(f["threshold"]), json.loads(str(f["meta"])))


@functools.lru_cache(maxsize=1)
def detector() -> Detector | None:
    """The shipped detector, or None (with a warning) when it was made for another head than the shipped one:
    its vectors would not be the ones it learned from."""
    from jgrounding.semantics import head as semantic_head

    d = read_detector()
    if semantic_head.made_for_another_head(
        d.meta,
        f"{DETECTOR_ASSET.name} was trained for head {{made}}, the shipped head is {{shipped}}: the learned no-motion "
        "detector is off (only the rule decides) until `python -m tools.train_nomotion` retrains it",
    ):
        return None
    return d


def sentence_vectors(texts) -> np.ndarray | None:
    """The shipped head's sentence vectors ``(N, 384)`` of ``texts`` (its one program,
    :func:`jgrounding.semantics.embedded.predict_tuned_many`), for a backend that did not compute them; None for a
    head that does not run as one program."""
    from jgrounding.semantics import embedded
    from jgrounding.semantics import head as semantic_head

    head = semantic_head.load()
    if not head.config.features.one_program:
        return None
    return embedded.predict_tuned_many(head, list(texts))[3]


def _re(p: str) -> re.Pattern:
    return re.compile(p, re.IGNORECASE)


_PERSON = (
    r"(?:patient|dog|cat|baby|child|kid|son|daughter|friend|colleague|partner|husband|wife|boyfriend|girlfriend|"
    r"mother|father|mum|mom|dad|grandma|grandad|brother|sister|courier|driver|tourist|audience|players?|class|team|"
    r"intern|waiter|barista|nurse|doctor|tutor|student|teacher|customer|cleaner|receptionist|caller|another|"
    r"others|each other|someone|somebody|camera|laptop|screen|phone|headset|whoever)"
)
_MOTION = (
    r"(?:wav\w*|aim\w*|extension|throw\w*|nod\w*|hug\w*|embrac\w*|cuddl\w*|curl\w*|coil\w*|swing\w*|sway\w*|"
    r"shak\w*|point\w*|beckon\w*|"
    r"reach\w*|offer\w*|present\w*|lean\w*|pat|pats|patting|strok\w*|comfort\w*|sooth\w*|consol\w*|cheer\w*|"
    r"celebrat\w*|trumpet\w*|flourish\w*|prob\w*|sniff\w*|snuffl\w*|explor\w*|investigat\w*|inspect\w*|examin\w*|"
    r"extend\w*|retract\w*|withdraw\w*|retreat\w*|back(?:ing)? (?:off|away)|back-off|pull(?:ing)? back|draw back|"
    r"move away|give (?:them|him|her) (?:some )?(?:space|room)|droop\w*|sink\w*|relax\w*|rest|settle\w*|go limp|"
    r"take it easy|lift\w*|rais\w*|bow|bows|wrap\w*|envelop\w*|approach\w*|greet\w*|welcom\w*|farewell|see (?:them|"
    r"him|her) off|send (?:them|him|her) off|wiggl\w*|bounc\w*|danc\w*|shimmy|rock\w*|dip\w*|bob\w*|tilt\w*|"
    r"bend\w*|fold\w*|tuck\w*|lower\w*|nuzzl\w*|invit\w*|come-closer|come (?:in )?(?:here|closer|close|over)|"
    r"get (?:as )?close\w*|closer|listen\w*|attentive\w*|attention|hear (?:them|him|her) out|focus\w* on|"
    r"turn\w* toward|hello|hi|bye|goodbye|high-five|push\w*|hand (?:her|him|them|it|over|the)|pass (?:the|it)|"
    r"hold (?:it |them )?out|shy\w*|spiral\w*|stretch\w*|erupt\w*|roll\w*|wind|winds|refus\w*|declin\w*|agree\w*|"
    r"acknowledg\w*|touch\w*|tap\w*|caress\w*|indicat\w*|show (?:them |him |her )?(?:where|the way)|clap\w*|"
    r"applau\w*|yes|no way)"
)
_MOTION_RE = _re(r"\b" + _MOTION + r"\b")
_FILLER = _re(
    r"^(?:\s|\W|op\b|opert?ator\b|please\b|just\b|so\b|then\b|now\b|right now\b|and\b|instead\b|rather\b|ok\b|"
    r"okay\b|better\b|simply\b|only\b|but\b|this time\b|plan\b|motion\b|response\b|best response\b|"
    r"i'?ll\b|i will\b|let'?s\b|we'?ll\b|i'?m going to\b|(?:\w+ly\b))+"
)
_VERBS = (
    r"(?:"
    + _MOTION
    + r"|give|do|make|go|match|try|use|get|let|throw|aim|freeze|bring|show|put|keep|stay|hold|turn|start|move|"
    r"come|say|answer|respond|mirror|return|sweep|open|take|study|check|follow|hear|calm|roll|wind|see|wish|bid|"
    r"send|hide|focus|pay|perform|wag|twirl|spin|rise|drop|signal|mimic|copy|draw|snuggle|pull|shrink|recoil)"
)
_DIRECTIVE_VERB = _re(
    r"^(?:(?:with|wiht|at|in|over|like|hardly|as|very|really|quite)\b(?:\s+\S+){0,4}?\s+)?" + _VERBS + r"\b"
)
_DEGREE = "|".join(re.escape(w) for words in DEGREE.values() for w in words if " " not in w)
_NOT_BASE = _re(r"^\w{3,}(?:ing|ed)\b(?! (?:him|her|them|it|the trunk)\b)")
_INTENSITY_START = _re(
    r"^(?:a |an |the |one )?(?:big|bigger|biggest|max|maximal|maximum|full|small|smaller|tiny|slight|little|gentle|"
    r"soft|subtle|moderate|medium|normal|regular|standard|ordinary|clear|firm|strong|huge|light|quick|slow|steady|"
    r"energetic|all-out|emphatic|exaggerated|lazy|loose|warm|broad|wide|minimal|barely|very|obvious|heartfelt|"
    r"deep|proper|happy|brief|short|long|single|polite|friendly|calm|pronounced|" + _DEGREE + r")\b(?:[\s,-]+\S+){0,5}?"
    r"[\s,-]+" + _MOTION + r"\b"
)
_MODAL = _re(
    r"\b(?:robot|trunk|tip|unit|arm|it|you|we|i)\s+(?:\w+\s+)?(?:should|must|needs? to|has to|ought to|will|can)\s+"
    r"(?:\w+ly\s+)?" + _VERBS + r"\b|^(?:should|let the|let your|have the|the robot should)\b"
)
_ROBOT_DOES = _re(r"\b(?:robot|trunk|tip)\s+(?:\w+ly\s+)?(?:" + _MOTION + r")(?:s|es)\b")
_EVALUATIVE = _re(
    r"\b(?:better|best|enough|fits|fitting|kinder|is right|is fine|works|called for|gives permission|says (?:no|yes)|"
    r"is the (?:way|answer|move))\b|\bonly\s*$"
)
_HYPOTHETICAL = _re(
    r"\b(?:would|could|(?<!your )might|may|if|once|considered|tempting|normally|usually|earlier|last|yesterday|"
    r"tomorrow|"
    r"next time|maybe|later|before|i'?d|we'?d|was|were|worth|isn'?t|aren'?t|wasn'?t|is not|no sense|too|pointless|"
    r"premature|odd|intrusive|invasive|wrong|off the table|unhelpful|pushy|impossible|not possible|can wait)\b"
)
_SKIP = _re(r"skip|forget|instead of|rather than|hold off|in place of")
_AND_THEN = _re(r"\s(?:and|then)\s+(?=(?:just |simply )?" + _VERBS + r"\b)")
_CLAUSE = re.compile(
    r"[.;:!?\n\u2014\u2013()]+|\s-{1,2}\s|,\s*(?=but\b|so\b|then\b|instead\b)|\bbut\b|\band then\b", re.I
)

# Phrases that say, in so many words, that no motion is wanted (kind, pattern).
_CUE_TEXT = {
    "freeze_order": (
        r"\bfreez(?:e|ing)\b|\bdo(?:n'?t| not) move\b|\bnot (?:to )?move at all\b|\bhold (?:position|"
        r"still|that pose|it there)\b|\bstay(?:s|ing)? (?:(?:completely|totally|perfectly|dead) )?(?:still|put|"
        r"static|motionless|frozen|where it is)\b|\bkeep(?:ing)? (?:(?:the )?(?:trunk|arm|tip|it) )?(?:\w+ly )?"
        r"(?:still|motionless|static|in place|exactly where)|\bstop all (?:gestures|motion|movement)|(?:^|"
        r"[.!?;]\s+)stop\s*(?:[.!?]|$)|"
        r"\bunder no circumstances\b|\bno (?:\w+ )?(?:movement|motion)s? for\b|\bnothing moves\b|\bstationary\b|"
        r"\bstays? (?:static|passive)|\bmust not (?:move|curl|swing)|\bdon'?t add any motion"
    ),
    "rules_out": (
        r"\bno need (?:to|for) (?:\w+ ){0,2}?(?:"
        + _MOTION
        + r"|react|respond|move|do|any)|\bleave (?:it|the (?:trunk|arm) (?:alone|be))\b|"
        r"\bleaving the (?:trunk|arm) be\b|"
        r"\blet it be\b|\bnothing for (?:the )?(?:trunk|arm|robot|us|it)\b|\bno (?:\w+ )?(?:trunk |"
        r"arm )?(?:movement|motion|"
        r"action|reaction|response|gesture)s?\b(?! (?:is|are) (?:\w+ )?(?:better|best|needed))|\bno anything\b|"
        r"\b(?:response|action|motion|reaction): none\b|\bnot worth (?:a|an|the)\b|\bskip it\b|\boff the table\b|"
        r"\b(?:isn'?t|not) (?:needed|required|warranted|expected)\b|\bno (?:\w+ ){0,2}?(?:gesture|motion|movement|"
        r"reaction|response|action|" + _MOTION + r")\w* (?:is |are )?(?:needed|required|warranted|expected)\b|"
        r"(?:^|[.!?]\s+)no (?:" + _MOTION + r"|gesture|movement|anything)\w*(?:, no (?:\w+ )?(?:" + _MOTION + r"|"
        r"gesture|movement|anything)\w*)+\b|(?:^|[.!?;]\s+)no (?:" + _MOTION + r")\w*\s*(?:[.!;]|$)|"
        r"\bnothing (?:here )?(?:requires|needed|called for)\b|\b(?:trunk|arm|it) (?:stays|remains|keeps) "
        r"(?:where it is|(?:\w+ (?:and )?)?(?:still|motionless|static|relaxed and motionless|quiet))|\bnot to be "
        r"(?:distracted|disturbed|interrupted)\b|\bdefault pose\b|"
        r"\bdoes nothing\b|\bdo nothing\b(?! much)|\bjust stillness\b|\bnot (?:to )?(?:do|move) anything\b|"
        r"\b(?:kindest|best) (?:thing|response) is to (?:not|leave|do nothing|stay)|(?:^|"
        r"[.!?;:]\s+)(?:nothing|holding|hold|"
        r"still|idle|none|hold(?:ing)? still)\s*(?:[.!?]|$)"
    ),
    "not_now": (
        r"(?:(?:^|[.;:!,]\s*|\b(?:just|best to|and|hold and|to) )wait|\bkeep waiting)\b(?!\s+for\s+(?:their|"
        r"thier|the\s+\w+'?s?|his|"
        r"her|a|your)\s+(?:\w+\s+)?(?:reaction|response|reply|answer|cue|turn))|\bcan wait\b|\bnot yet\b|"
        r"\b(?:just a|one) (?:moment|minute|sec(?:ond)?)\b|"
        r"\bnothing to do (?:yet|till|until|now|right now)\b|\b(?:he|she|they)(?:'ll| will) (?:be back|come back|"
        r"chat after)|\buntil (?:he|she|they)(?:'s| is| are)? ?(?:wakes?|finish|comes?|off)\b|\broom is empty\b|"
        r"\bchair is empty\b|\baway from (?:the |her |his )?desk\b|\bstepped out (?:of the room|for|a)\b"
    ),
    "addressed_other": (
        r"\b(?:not|n'?t) (?:(?:specifically|directly|really|meant) )?(?:for|at|to|directed at|aimed at|meant for|"
        r"addressed to) (?:the robot|the unit|the trunk|us|it)\b|, not (?:at |to |for )?(?:the robot|us|it)\b|"
        r"\bnothing to do with (?:the robot|us)\b|\bnone of it (?:is )?(?:for|aimed at) us\b|\b(?:is|are|was|were) "
        r"(?:for|aimed at|meant for|directed at|addressed to) (?:her|him|them|whoever|the (?:audience|\w+)|his "
        r"\w+|her \w+)|\bbetween (?:the two of )?them\b|"
        r"\b(?:voicemail|facetime|conference call|teams call|zoom call|text-to-speech|into the (?:headset|phone))\b"
    ),
    "observed_activity": (
        r"\bnot looking up\b|\b(?:isn'?t|is not) part of\b|\bgoes back to (?:typing|work|reading)\b|\bdoesn'?t "
        r"concern\b|\bnothing here involves\b|\bnobody (?:is )?addressing\b|\bhaven'?t looked over\b|"
        r"\bjust furniture\b|\bnot engaging\b|\bnot looking (?:at|anywhere near) (?:us|the robot)\b"
    ),
    "handling": (
        r"\bcalibration mode\b|\btest rig\b|\bclamped\b|\bbubble wrap\b|\bmaintenance log\b|\bby hand\b|"
        r"\bleak test\b|\bhands all over it\b|\binspecting the (?:tip|trunk)\b|\bcable-tying\b|"
        r"\b(?:robot|trunk|unit)\b[^.]{0,30}\bbeing (?:cleaned|wheeled|repaired|serviced|shipped|calibrated|"
        r"inspected|"
        r"moved)\b|\bbeing (?:pulled|wrapped|fitted|cleaned) (?:over|around|on) the (?:trunk|tip|robot)\b"
    ),
}
_CUES = [(kind, _re(p)) for kind, p in _CUE_TEXT.items()]
# Speech quoted and addressed to someone else: "Manager to intern: '...'", "... says 'bye' to the driver".
_SPEECH_TO = _re(
    r"^[^'\"\u201c:]{0,60}\bto (?!(?:the )?(?:robot|unit|trunk|us|me)\b)(?:the |her |his |a |an |my |their )?"
    r"[\w-]+(?: [\w-]+)?\s*:\s*['\"\u201c]"
)
_SAYS_TO = _re(
    r"\b(?:(?:says?|said|shouts?|murmurs?|whispers?|yells?|calls?|calling|read(?:s|ing)? (?:aloud|"
    r"out))\b(?:\s+\S+){0,8}?\s+to|tells?|told|asks?|"
    r"asked|calling)\s+(?:(?:her|his|their|my) \w+|(?:the |a |an |one |each )?" + _PERSON + r")\b"
)
_MOTION_TO = _re(
    r"\b(?:wav|point|beckon|nod|hug|cheer|clap|high-fiv)\w*\b(?:\s+\S+){0,5}?\s+(?:to|at|toward|towards) "
    r"(?:a|an|the|her|his|their|each) " + _PERSON + r"\b"
)
_ENGAGED = _re(r"\b(?:robot|trunk|unit|you|me)\b")
_ENGAGED_USER = _re(r"\b(?:robot|trunk|unit|you|me|user)\b")
# Single-quoted speech that contains apostrophes ('Hi, it's Tom'), which structure's quotes leave out.
_SINGLE_QUOTED = re.compile(r"(?:(?<=^)|(?<=[\s(:]))'((?:[^']|(?<=\w)'(?=\w))+?)'(?=$|[\s.,;:!?)])")
_AMONG = _re(
    r"\bto each other\b|\bamong themselves\b|\bwith each other\b|\b(?:asks?|asked|tells?|told) (?:the|her|his|their) "
    + _PERSON
    + r" to\b"
)
_CALL = _re(r"\b(?:(?:on|in) (?:a|the) (?:video|phone|zoom|work) (?:call|meeting)|video call|on the phone)\b")
_BUSY = _re(r"\b(?:scrolling|typing|knitting|ironing|vacuuming|mopping|sewing|chopping|doing a jigsaw)\b")


def _quoted(text: str, st: structure.Structure) -> list:
    """Quoted spans: structure's, and single-quoted speech with apostrophes inside."""
    return [*st.quoted, *([m.span(1) for m in _SINGLE_QUOTED.finditer(text)] if "'" in text else [])]


def _masked(text: str, st: structure.Structure) -> str:
    """The text with its rejected and quoted spans blanked (same length), so their words choose nothing; "skip
    the X and Y" rejects X only."""
    chars, rejected = list(text), []
    for a, b in st.rejected:
        cut = _AND_THEN.search(text, a, b) if _SKIP.match(text, a) else None
        rejected.append((a, cut.start() if cut else b))
    for a, b in (*rejected, *_quoted(text, st)):
        chars[a:b] = " " * (b - a)
    return "".join(chars)


def chosen_motion(text: str, st: structure.Structure | None = None) -> str | None:
    """The first clause that chooses a motion outside what the text rules out (None: none does): an order
    ("beckon him over"), "the trunk should ...", "let the trunk relax", "a tiny nod is enough", "big hug", "the
    robot folds inward"; clauses that are hypothetical or negated ("a hug would be too much") choose nothing."""
    st = st or structure.spans(text)
    masked, start = _masked(text, st), 0
    for cut in (*_CLAUSE.finditer(masked), None):
        end = cut.start() if cut else len(text)
        clause, whole, start = masked[start:end], text[start:end], cut.end() if cut else end
        c = _FILLER.sub("", clause.strip()).strip()
        if not c or not _MOTION_RE.search(c) or _HYPOTHETICAL.search(whole):
            continue
        if (
            (_DIRECTIVE_VERB.match(c) and not _NOT_BASE.match(c))
            or _INTENSITY_START.match(c)
            or _MODAL.search(c)
            or _ROBOT_DOES.search(c)
            or _EVALUATIVE.search(c)
        ):
            return c
    return None


def check(
    text: str,
    st: structure.Structure | None = None,
    vector=None,
    *,
    learned: bool = True,
    learned_detector: Detector | None = None,
) -> Hold | None:
    """A :class:`Hold` when the text calls for no motion (see the module docstring), else None: the rule first,
    then (with ``learned``) the detector on ``vector``, the text's sentence vector ``(384,)`` (None: computed here,
    one encoder pass, only when the rule lets the text through); a chosen motion overrides either.
    ``learned_detector``: another detector than the shipped one (:func:`detector`), e.g. the shipped one at another
    threshold (``tools.nomotion_frontier``)."""
    st = st or structure.spans(text)
    hold = rule(text, st)
    if hold is None and learned and (d := learned_detector or detector()) is not None:
        if vector is None:
            vectors = sentence_vectors([text])
            vector = None if vectors is None else vectors[0]
        if vector is not None and (p := float(d.probability(np.asarray(vector)[None])[0])) >= d.threshold:
            hold = Hold(LEARNED, f"learned detector, p = {p:.2f}", p)
    if hold is None or chosen_motion(text, st):
        return None
    return hold


def rule(text: str, st: structure.Structure) -> Hold | None:
    """The hand-written rule's :class:`Hold` before the :func:`chosen_motion` guard, or None."""
    hold = None
    for kind, pattern in _CUES:
        if m := pattern.search(text):
            hold = Hold(kind, m.group(0).strip(" ,.;:"))
            break
    quoted = bool(_quoted(text, st))
    if hold is None and (quoted and (m := _SPEECH_TO.search(text))):
        hold = Hold("addressed_other", m.group(0).strip(" :'\"\u201c"))
    masked = _masked(text, st)
    if hold is None and not _ENGAGED.search(masked):
        if (quoted and (m := _SAYS_TO.search(masked))) or (m := _MOTION_TO.search(masked)):
            hold = Hold("addressed_other", m.group(0).strip())
    if hold is None and not _ENGAGED.search(text) and (m := _CALL.search(masked)):
        hold = Hold("addressed_other", m.group(0).strip())
    if hold is None and not _ENGAGED_USER.search(text):
        if m := _AMONG.search(masked):
            hold = Hold("addressed_other", m.group(0).strip())
        elif m := _BUSY.search(masked):
            hold = Hold("observed_activity", m.group(0).strip())
    return hold


def apply(
    text: str,
    g: Grounding,
    st: structure.Structure | None = None,
    vector=None,
    *,
    learned: bool = True,
    learned_detector: Detector | None = None,
) -> Grounding:
    """``g`` held (``confident=False``, ``no_motion`` its kind, ``reason`` why) when :func:`check` holds ``text``;
    otherwise ``g`` unchanged. The intent and intensity stay the reducer's most likely ones. ``vector``: the
    text's sentence vector when the reducer computed it (the embedded backend), else :func:`check` computes it.

    A learned hold of a grounding the reducer already did not act on keeps the reducer's reason first ("a system
    or log line (reads as no behaviour, p = 1.00); the text calls for no motion (learned detector, p = 0.99)"):
    the detector says no more than that the text calls for no motion, the reducer often says what kind of text
    it is.

    A held grounding's ``confidence`` is the reducer's p(m) times the probability that the text asks for a motion
    at all, ``1 - hold.p`` (0 for the rule's holds, one minus the detector's p for its own): how sure the whole
    decision is that the tuple is the motion to make, so a held text no longer reports the reducer's confidence
    in a motion it was held from. ``scores`` keep the reducer's distribution. ``learned``, ``learned_detector``: as
    :func:`check`'s (the defaults are what every front end uses)."""
    hold = check(text, st, vector, learned=learned, learned_detector=learned_detector)
    if hold is None:
        return g
    reason = f"{g.reason}; {hold.reason}" if hold.kind == LEARNED and not g.confident and g.reason else hold.reason
    confidence = round(g.confidence * (1.0 - hold.p), 4)
    return dataclasses.replace(g, confident=False, reason=reason, no_motion=hold.kind, confidence=confidence)
