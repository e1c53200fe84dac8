"""Generated training corpus for the semantic head: templates written from the vocabulary, never from eval text.

``python -m tools.semantics_corpus`` writes ``assets/semantics/train/corpora/generated.jsonl`` (deterministic:
one seeded numpy generator). Each line is ``{"text", "intent", "intensity"}``; ``intent`` may be ``"none"``
for text that asks for no trunk behaviour at all (interface commands, keyboard noise, unrelated facts), which
teaches the head to say it is unsure instead of guessing a motion.

Sources of the phrases: the canonical descriptions in :mod:`jgrounding.vocabulary`, and the phrase lists
below, written for this file by hand (actions, situations, user states, refusals and agreements without the
intent's own name, parts of the trunk). The evaluation sets were never read while writing them.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from jgrounding import vocabulary as voc
from jgrounding.vocabulary import INTENSITIES, INTENTS
from tools import semantic_sets

ROOT = Path(__file__).resolve().parent.parent
OUT = semantic_sets.path("train/corpora", "generated.jsonl")
# The dev and test splits: a generated line that happens to be one of their texts (short commands such as "Come
# here.") is dropped, so that no training text is one the project evaluates on
# (tests/semantics/test_training_data.py). Only their texts are compared; nothing else is read from them.
EVAL_SPLITS = tuple(path for s in semantic_sets.select(reader="corpus") for path in s.files)
SEED = 0
PER_INTENT = 200  # generated examples per intent
NUM_NONE = 240

# What the trunk should do, phrased as imperatives (no subject).
ACTIONS = {
    "greeting": [
        "wave hello",
        "say hi with the trunk",
        "greet them",
        "lift the trunk and wave to say hello",
        "welcome the visitor",
        "raise the trunk in a friendly hello",
        "give a hello wave",
        "swing the trunk tip side to side as a greeting",
        "acknowledge their arrival with a wave",
        "say good morning",
        "wave to the newcomer",
        "greet the guest at the door",
    ],
    "farewell": [
        "wave goodbye",
        "say bye",
        "see them off",
        "bid them farewell",
        "wave them off as they go",
        "lower the trunk in a slow goodbye wave",
        "send them off with a wave",
        "say see you later",
        "wave as they walk out",
        "give a parting wave",
        "say good night and wave",
        "wish them a safe trip home",
    ],
    "comforting": [
        "comfort them",
        "console the user",
        "gently pat their shoulder",
        "soothe them with a soft touch",
        "reassure them",
        "stroke their arm softly",
        "offer some comfort",
        "be there for them with a calm touch",
        "rest the tip on their shoulder to console them",
        "calm them down with a slow caress",
        "give them a reassuring pat",
        "show sympathy with a tender touch",
    ],
    "attentive_listening": [
        "listen to them",
        "pay close attention",
        "lean in and hold still while they talk",
        "stay quiet and attentive",
        "show that I'm listening",
        "tilt the tip and listen",
        "hear them out",
        "keep still and focus on what they say",
        "lean toward the speaker",
        "give them my full attention",
        "stay present while they explain",
        "follow their story quietly",
    ],
    "curiosity": [
        "explore the new object",
        "sniff around it",
        "investigate what they brought",
        "examine the box",
        "probe the thing with the tip",
        "check out what's on the table",
        "inspect the toy curiously",
        "reach out and feel the strange item",
        "take a closer look",
        "study the unfamiliar gadget",
        "snuffle at the bag to see what's inside",
        "poke at it with interest",
    ],
    "embracing": [
        "hug them",
        "give them a hug",
        "wrap the trunk around them",
        "embrace the user",
        "cuddle them",
        "hold them close",
        "give them a warm squeeze",
        "envelop them in the trunk",
        "circle the trunk around their shoulders",
        "pull them into an embrace",
        "wrap them up warmly",
        "give a bear hug",
    ],
    "withdrawal": [
        "back away",
        "give them space",
        "pull the trunk back",
        "retreat",
        "move away from them",
        "retract the trunk",
        "keep the distance",
        "draw back from the user",
        "stay out of their way",
        "withdraw the trunk toward the body",
        "back off a bit",
        "get out of their personal space",
    ],
    "coiling": [
        "curl up",
        "coil the trunk",
        "roll the tip inward",
        "curl the end of the trunk into a spiral",
        "tuck the trunk in close to the body",
        "wind the trunk up tightly",
        "curl into itself",
        "fold the trunk up shyly",
        "twist the tip into a tight coil",
        "roll the trunk up like a spring",
        "hide by curling the trunk",
        "wrap the trunk around itself",
    ],
    "playful_swing": [
        "swing around playfully",
        "sway back and forth for fun",
        "bounce to the beat",
        "dance with the trunk",
        "wiggle the trunk playfully",
        "swing the trunk like a pendulum",
        "be goofy and swing",
        "rock from side to side to play",
        "groove to the music",
        "do a silly swaying dance",
        "swing loosely to amuse the kids",
        "shimmy the trunk",
    ],
    "nodding": [
        "nod",
        "nod in agreement",
        "bob the trunk up and down",
        "acknowledge with a nod",
        "agree",
        "signal yes",
        "move the trunk up and down to say yes",
        "confirm with a nod",
        "give an approving nod",
        "show that I understood",
        "dip the trunk to agree",
        "say yes",
    ],
    "refusing": [
        "shake the trunk no",
        "refuse",
        "decline",
        "say no",
        "turn it down",
        "shake side to side to disagree",
        "reject the request",
        "signal no",
        "deny the request",
        "wag the trunk side to side, meaning no",
        "make it clear that it's not okay",
        "don't allow it",
    ],
    "beckoning": [
        "beckon them over",
        "invite them to come closer",
        "call them over",
        "motion for them to approach",
        "gesture come here",
        "curl the tip back toward me to call them",
        "wave them in",
        "encourage them to step nearer",
        "ask them to come over",
        "signal them to join us",
        "draw them in with a come-hither curl",
        "invite the child to come near",
    ],
    "pointing": [
        "point at the door",
        "point to the exit",
        "show them where it is",
        "indicate the direction",
        "point the way to the kitchen",
        "extend the trunk toward the shelf",
        "show which way to go",
        "direct their attention to the window",
        "point out the lost keys",
        "aim the trunk at the sign",
        "point toward the bathroom",
        "stretch straight out toward the object",
    ],
    "celebrating": [
        "celebrate",
        "cheer",
        "throw the trunk up in celebration",
        "trumpet with joy",
        "do a victory flourish",
        "party with them",
        "congratulate them",
        "raise the trunk high and cheer",
        "rejoice with them",
        "celebrate the good news",
        "do a happy flourish",
        "make a triumphant gesture",
    ],
    "resting": [
        "relax",
        "rest",
        "let the trunk droop",
        "stay idle",
        "hang loose",
        "take a break",
        "settle down",
        "go quiet and rest",
        "let the trunk hang down",
        "doze off",
        "stay calm and do nothing much",
        "power down and relax",
    ],
    "offering": [
        "hand it over",
        "offer them the cup",
        "give them the toy",
        "pass the object to them",
        "present the gift",
        "hold out the flower for them",
        "hand them the ball",
        "reach out with the item",
        "offer a snack",
        "give the book back",
        "extend the trunk to hand over the keys",
        "offer them the pen",
    ],
}

# Situations and user states that call for the intent; a few carry their own intensity (level, text).
SITUATIONS = {
    "greeting": [
        "a visitor just walked in",
        "the user arrived",
        "someone new entered the room",
        "the kids came home from school",
        "a guest is at the door",
        "the user just sat down in front of me",
    ],
    "farewell": [
        "the user is leaving",
        "they're heading out",
        "the guest is going home",
        "the meeting is over and they're off",
        "the child is going to bed",
        "they're putting on their coat to go",
    ],
    "comforting": [
        "the user seems sad",
        "they look upset",
        "the user is lonely",
        "they had a rough day",
        "the user just got bad news",
        "they're worried about tomorrow",
        (0, "the user seems a little down"),
        (0, "they look slightly disappointed"),
        (2, "the user is very upset"),
        (2, "they are crying"),
        (3, "the user is distraught and sobbing"),
        (3, "they are in tears, completely heartbroken"),
    ],
    "attentive_listening": [
        "the user is telling a story",
        "they want to talk",
        "the user is explaining something",
        "they're sharing their feelings",
        "the user started speaking",
        "they have something to say",
    ],
    "curiosity": [
        "there's a new object on the table",
        "the user brought a strange box",
        "something unfamiliar appeared",
        "a new toy is lying nearby",
        "there's an odd noise from the bag",
        "the user shows me a gadget",
    ],
    "embracing": [
        "the user wants a hug",
        "they opened their arms",
        "the user missed me",
        "they need a warm embrace",
        "the child asked for a cuddle",
        "an old friend is back",
    ],
    "withdrawal": [
        "the user looks uncomfortable",
        "they flinched when I moved",
        "the user asked me to stop",
        "I'm too close to them",
        "they seem annoyed",
        "they want to be alone",
        (2, "the user looks scared of the trunk"),
        (3, "the user is terrified and screaming"),
    ],
    "coiling": [
        "I feel shy",
        "I'm embarrassed",
        "everyone is staring at me",
        "I'm nervous around strangers",
        "I was complimented and feel bashful",
        "I feel timid",
    ],
    "playful_swing": [
        "music is playing",
        "the kids want to play",
        "it's party time",
        "the user is joking around",
        "we're playing a game",
        "everyone is in a silly mood",
    ],
    "nodding": [
        "the user asked if I understood",
        "they made a good point",
        "the user asked for confirmation",
        "they said something I agree with",
        "they asked 'are you ready?'",
        "the user checks that I got it",
    ],
    "refusing": [
        "the user asked for something forbidden",
        "they want me to do something unsafe",
        "the user asked for another cookie before dinner",
        "they asked me to break the rules",
        "that request is not allowed",
        "they want me to lift the heavy box",
    ],
    "beckoning": [
        "the user is standing far away",
        "the child is hesitating at the door",
        "they seem unsure whether to approach",
        "I want them to come nearer",
        "the shy kid is hiding behind the sofa",
        "they can't hear me from over there",
    ],
    "pointing": [
        "the user asked where the door is",
        "they lost their keys",
        "they're looking for the toilet",
        "the user asked which way to go",
        "they can't find the remote",
        "they asked where the exit is",
    ],
    "celebrating": [
        "we won",
        "the user got the job",
        "it's their birthday",
        "they passed the exam",
        "the team scored",
        "they finished the project",
        (0, "they got a small win today"),
        (0, "a minor success"),
        (3, "they won the championship"),
        (3, "an enormous victory"),
    ],
    "resting": [
        "nothing is happening",
        "the user is asleep",
        "the room is quiet",
        "there's nothing to do",
        "it's late at night",
        "the user is reading quietly",
    ],
    "offering": [
        "the user wants the cup",
        "they asked for the toy",
        "they reached for the book",
        "the user needs a pen",
        "it's their gift",
        "they asked me to pass the salt",
    ],
}

# Whole responses that describe the behaviour without its usual name (the classes that fool cue lists).
EXTRA = {
    "refusing": [
        "No.",
        "No, that's not allowed.",
        "That's forbidden.",
        "Absolutely not.",
        "Nope, not happening.",
        "I can't let you do that.",
        "Sorry, the answer is no.",
        "That's off limits.",
        "No way.",
        "I won't do that.",
        "Not allowed, sorry.",
        "Tell them no by shaking the trunk.",
    ],
    "nodding": [
        "Yes.",
        "Yes, sounds good.",
        "Okay, I agree.",
        "Sure, that works.",
        "Right, got it.",
        "Yep, understood.",
        "Exactly, you're right.",
        "Mm-hmm, I follow.",
        "Of course.",
        "Sounds like a plan.",
        "Signal approval with a vertical motion.",
        "Move up and down to approve.",
    ],
    "coiling": [
        "Roll the end inward.",
        "Curl the tip in on itself.",
        "Wind the distal segments into a spiral.",
        "Draw the tip in toward the base in a tight curl.",
        "Turn the end of the trunk into a little spiral.",
        "Fold the tip back into a coil near the body.",
    ],
    "beckoning": [
        "Come here.",
        "Come on over!",
        "Come closer, please.",
        "Over here!",
        "Invite them nearer.",
        "Get them to approach.",
        "Ask the child to come toward me.",
        "Encourage them to draw near.",
    ],
    "celebrating": [
        "Yay!",
        "Hooray, we did it!",
        "Woohoo!",
        "A little celebration is in order.",
        "Well done, let's celebrate a bit.",
        "Congratulations!",
    ],
    "resting": ["Just chill.", "Nothing needed right now.", "Stand by quietly.", "Stay relaxed.", "Take it easy."],
    "withdrawal": ["Don't get closer.", "Stop approaching them.", "Don't touch them.", "Keep away."],
    "attentive_listening": ["Don't interrupt, just listen.", "Stay quiet and let them finish.", "I'm all ears."],
}

DEGREE = {
    0: [
        "slightly",
        "barely",
        "a little",
        "gently",
        "softly",
        "subtly",
        "discreetly",
        "faintly",
        "lightly",
        "just a tiny bit",
        "with a small motion",
        "in a low-key way",
        "tentatively",
        "with restraint",
        "with a hint of motion",
        "minimally",
        "quietly and politely",
        "very gently",
        "hardly at all",
    ],
    1: [
        "",
        "",
        "",
        "calmly",
        "normally",
        "moderately",
        "at a comfortable pace",
        "in a relaxed way",
        "steadily",
        "casually",
        "with a medium motion",
        "in a friendly way",
        "at an ordinary pace",
        "simply",
    ],
    2: [
        "clearly",
        "noticeably",
        "with a big motion",
        "strongly",
        "warmly",
        "with lively energy",
        "firmly",
        "eagerly",
        "very clearly",
        "expressively",
        "with a wide sweep",
        "visibly",
        "really",
        "with conviction",
        "energetically",
        "in a pronounced way",
    ],
    3: [
        "wildly",
        "as much as possible",
        "with full energy",
        "emphatically",
        "enthusiastically",
        "with all your might",
        "extremely hard",
        "vigorously",
        "like crazy",
        "over the top",
        "as big as you can",
        "frantically",
        "urgently, right now",
        "at full force",
        "with maximum intensity",
        "explosively",
        "totally all out",
    ],
}
EMOTION = {  # how strongly the user feels, for situations that do not carry their own level
    0: ["a bit", "slightly", "mildly", "somewhat"],
    1: ["", "", "fairly"],
    2: ["very", "really", "quite", "deeply"],
    3: ["extremely", "overwhelmingly", "incredibly", "utterly"],
}
SUBJECTS = [
    "",
    "",
    "",
    "I should ",
    "I will ",
    "Let's ",
    "Please ",
    "The robot should ",
    "The trunk should ",
    "It should ",
    "You should ",
    "Go ahead and ",
    "Time to ",
    "Plan: ",
    "Response: ",
    "Best response: ",
]
TYPOS = {
    "the": "teh",
    "you": "yuo",
    "with": "wiht",
    "gently": "gentley",
    "really": "realy",
    "their": "thier",
    "slightly": "slighty",
    "because": "becuase",
    "around": "aroudn",
    "goodbye": "goodbey",
}
BRITISH = {
    "color": "colour",
    "favorite": "favourite",
    "behavior": "behaviour",
    "apologize": "apologise",
    "realize": "realise",
    "center": "centre",
    "mom": "mum",
    "program": "programme",
}

NONE = [
    "quit",
    "exit",
    "help",
    "stop the program",
    "q",
    "ok",
    "test",
    "asdf",
    "hello world program",
    ":wq",
    "what time is it",
    "the capital of France is Paris",
    "2 + 2 = 4",
    "print('hi')",
    "lorem ipsum dolor sit amet",
    "ls -la",
    "null",
    "undefined",
    "123456",
    "qwerty",
    "the stock market closed higher",
    "restart",
    "close the window",
    "save file",
    "sudo apt-get update",
    "import numpy as np",
    "error 404",
    "blah blah",
    "the quick brown fox jumps over the lazy dog",
    "photosynthesis converts light into energy",
    "invoice number 3321 is due on Friday",
    "turn off the computer",
    "cancel",
    "abort",
    "logout",
    "end",
    "none",
    "n/a",
    "???",
    "...",
    "hmm",
    "uh",
    "xyz",
    "foo bar baz",
    "random text",
    "select * from users",
    "the recipe needs two eggs",
    "compile the code",
    "the train departs at 9:40",
    "the weather report says rain",
]


def _level_words(rng, level):
    return DEGREE[level][rng.integers(len(DEGREE[level]))]


def _apply_noise(rng, text):
    words = text.split(" ")
    if rng.random() < 0.08:
        words = [TYPOS.get(w, w) for w in words]
    if rng.random() < 0.1:
        words = [BRITISH.get(w, w) for w in words]
    text = " ".join(words)
    if rng.random() < 0.3:
        text = text.lower()
    return text


def _one(rng, intent):
    """One generated (text, level) for ``intent``."""
    level = int(rng.integers(4))
    action = ACTIONS[intent][rng.integers(len(ACTIONS[intent]))]
    sit = SITUATIONS[intent][rng.integers(len(SITUATIONS[intent]))]
    sit_level = None
    if isinstance(sit, tuple):
        sit_level, sit = sit
    style = rng.random()
    adverb = _level_words(rng, level)
    bang = "!" * (1 + int(rng.integers(2))) if level == 3 and rng.random() < 0.4 else "."
    subj = SUBJECTS[rng.integers(len(SUBJECTS))]
    act = f"{action} {adverb}".strip() if rng.random() < 0.6 else f"{adverb} {action}".strip()
    if style < 0.3:  # terse command
        text = f"{subj}{act}{bang}"
    elif style < 0.6:  # situation; response plan
        if sit_level is not None:
            level = sit_level
            adverb = _level_words(rng, level) if rng.random() < 0.5 else ""
            act = f"{action} {adverb}".strip()
        text = f"{sit[0].upper()}{sit[1:]}; {subj.lower() or ''}{act}{bang}"
    elif style < 0.75 and intent in EXTRA:  # phrasing without the intent's usual words
        text = EXTRA[intent][rng.integers(len(EXTRA[intent]))]
        if rng.random() < 0.5 and adverb:
            text = f"{text.rstrip('.!')} {adverb}{bang}"
        else:
            level = 1 if text.endswith(".") else 2
    elif style < 0.85:  # third person description of the robot
        verb, _, rest = action.partition(" ")
        verb = {"do": "does", "go": "goes", "say": "says", "be": "is", "don't": "doesn't"}.get(verb, verb + "s")
        text = " ".join(f"The robot {verb} {rest} {adverb}".split()) + bang
    elif style < 0.93:  # the description itself, with the level
        text = f"The trunk {voc.INTENT_DESCRIPTIONS[intent].split('the trunk ', 1)[-1]}, {adverb or 'normally'}."
    else:  # long plan
        text = (
            f"Observation: {sit}. The user looks at me. Plan: {act}, then return to a neutral pose"
            f" and wait for their reaction{bang}"
        )
        if sit_level is not None:
            level = sit_level
    return _apply_noise(rng, text), level


def generate(seed: int = SEED) -> list[dict]:
    """The generated corpus: ``PER_INTENT`` lines per intent plus ``NUM_NONE`` no-behaviour lines."""
    rng = np.random.default_rng(seed)
    rows = []
    for intent in INTENTS:
        seen = set()
        while sum(r["intent"] == intent for r in rows) < PER_INTENT:
            text, level = _one(rng, intent)
            if text not in seen:
                seen.add(text)
                rows.append({"text": text, "intent": intent, "intensity": INTENSITIES[level]})
    letters = np.array(list("abcdefghijklmnopqrstuvwxyz"))
    for i in range(NUM_NONE):
        if i < len(NONE):
            text = NONE[i]
        else:
            n = int(rng.integers(1, 4))
            text = " ".join("".join(rng.choice(letters, int(rng.integers(2, 9)))) for _ in range(n))
        rows.append({"text": text, "intent": "none", "intensity": "moderate"})
    return rows


def normalized(text: str) -> str:
    """Lower case, words only: the form in which two texts count as the same."""
    return " ".join(re.findall(r"[a-z0-9']+", text.lower()))


def decontaminated(rows: list[dict], splits=EVAL_SPLITS) -> list[dict]:
    """``rows`` without those whose text (:func:`normalized`) is a text of ``splits``."""
    held = {
        normalized(json.loads(line)["text"])
        for path in splits
        for line in Path(path).read_text().splitlines()
        if line.strip()
    }
    return [r for r in rows if normalized(r["text"]) not in held]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(OUT))
    args = p.parse_args(argv)
    from jgrounding.io import write_atomic

    rows = decontaminated(generate())
    write_atomic(Path(args.out), "".join(json.dumps(r) + "\n" for r in rows))
    print(f"wrote {len(rows)} lines to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
