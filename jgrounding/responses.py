"""Open-vocabulary response texts that each (intent, intensity) tuple was reduced from (Sec. III-C.1).

The paper generates them with an MLLM over offline cue-history instances; we generate them from
templates with variety — situation x response plan x intensity modifier — phrased as an MLLM would
write a social response plan. The ``Raw`` ablation baseline conditions on their text embeddings.
The evaluation set for the text -> tuple reducer is written separately and never built from these.
"""

from __future__ import annotations

import numpy as np

from jgrounding.vocabulary import INTENSITIES, INTENTS

SITUATIONS = {
    "greeting": ["The user just walked in and waved at me.", "A visitor approached and said hello.",
                 "The user smiled at me from across the room.", "Someone new sat down in front of me."],
    "farewell": ["The user is packing up to leave.", "The user said they have to go now.",
                 "The session is ending and the user stood up.", "The visitor waved goodbye at the door."],
    "comforting": ["User seems sad; their voice is shaky.", "The user sighed and looked down at the floor.",
                   "The user mentioned a rough day and sounds tired.", "The user is tearful after a phone call."],
    "attentive_listening": ["The user is telling me a long story.", "The user started explaining a problem.",
                            "The user is speaking softly about their plans.", "The user asked me to listen for a moment."],
    "curiosity": ["The user placed an unfamiliar object on the table.", "The user hid something behind their back.",
                  "A new toy appeared near me.", "The user asked what I think of this strange gadget."],
    "embracing": ["The user opened their arms toward me.", "The user asked for a hug.",
                  "The user is celebrating good news and leans in close.", "The user looks lonely and reaches out."],
    "withdrawal": ["The user flinched when I moved closer.", "The user said I am too close.",
                   "The user raised a hand to keep distance.", "The user looks startled by my movement."],
    "coiling": ["A loud noise startled everyone in the room.", "The user teased me about being shy.",
                "The user is scolding me gently.", "Several strangers are crowding around me."],
    "playful_swing": ["The user is laughing and playing music.", "The user invited me to play a game.",
                      "Children are giggling around me.", "The user is dancing in front of me."],
    "nodding": ["The user asked if I understood.", "The user made a point I agree with.",
                "The user asked whether we should continue.", "The user is checking that I followed the steps."],
    "refusing": ["The user offered me something I should not take.", "The user asked me to do something unsafe.",
                 "The user asked if I want more candy and I should decline.", "The user suggested touching the stove."],
    "beckoning": ["The user is standing far away and looks unsure.", "The user hesitates at the doorway.",
                  "I want the user to come see something.", "A shy child is watching me from a distance."],
    "pointing": ["The user asked where the exit is.", "The user is looking for their keys, which are on the shelf.",
                 "The user asked which way to the kitchen.", "The user wants to know where to sit."],
    "celebrating": ["The user just won the game!", "The user announced they passed their exam.",
                    "The user shared wonderful news about a new job.", "The team scored and the user cheered."],
    "resting": ["The user is reading quietly.", "It is late and the room is calm.",
                "The user asked me to relax for a while.", "Nobody is interacting with me right now."],
    "offering": ["The user looks like they need a tissue.", "The user asked me to hand over the cup.",
                 "The user is reaching for the remote next to me.", "The user wants the flower I am holding."],
}

PLANS = {
    "greeting": ["greet them back with a wave", "say hello and wave toward them", "welcome them with a friendly wave"],
    "farewell": ["wave goodbye and then settle down", "see them off with a slow farewell wave", "bid them goodbye and lower the trunk"],
    "comforting": ["respond calmly and offer a gentle touch", "approach slowly and pat their shoulder",
                   "comfort them with a soft stroke"],
    "attentive_listening": ["lean in and listen attentively", "stay still, lean closer and show I am listening",
                            "tilt toward them and keep quiet attention"],
    "curiosity": ["explore it curiously with the tip", "sniff around it from side to side", "probe it with interest"],
    "embracing": ["wrap around them in a hug", "give them a warm embrace", "curl around them like a hug"],
    "withdrawal": ["back away and give them space", "retreat and bend away from them", "pull back to a respectful distance"],
    "coiling": ["curl up shyly", "coil the trunk inward to self-soothe", "tuck in and make myself small"],
    "playful_swing": ["swing playfully from side to side", "sway along in a bouncy, playful way", "do a loose playful swing"],
    "nodding": ["nod to show agreement", "bob up and down to acknowledge", "give an approving nod"],
    "refusing": ["shake the trunk to say no", "decline by shaking side to side", "refuse with a clear head-shake motion"],
    "beckoning": ["beckon them to come closer", "curl the tip back to invite them over", "wave them over toward me"],
    "pointing": ["point toward it and hold", "extend the trunk toward the right direction", "indicate the place by pointing"],
    "celebrating": ["celebrate with an energetic trumpet flourish", "rise up high and cheer with them",
                    "join the celebration with lively flourishes"],
    "resting": ["relax and stay quiet", "droop and rest calmly", "settle into a calm resting pose"],
    "offering": ["reach out and hand it over", "offer it to them with the tip curled up", "extend toward them to give it"],
}

MODIFIERS = {
    "subtle": ["Respond subtly: {p}, barely moving.", "Keep it small and gentle: {p}, just a little.",
               "Quietly {p}, slightly and slowly."],
    "moderate": ["Respond calmly: {p}.", "{P} at a comfortable, moderate pace.", "In a relaxed way, {p}."],
    "pronounced": ["Clearly {p}, with a noticeable motion.", "Respond expressively: {p}, reaching well toward them.",
                   "Make it obvious: {p} with a big, lively movement."],
    "emphatic": ["Enthusiastically {p}, with full energy!", "Respond emphatically: {p} as strongly as possible!",
                 "Go all out and {p}, fast and wide!"],
}


def response_texts(intent: int, intensity: int, count: int, rng: np.random.Generator) -> tuple[str, ...]:
    """``count`` distinct response texts for the tuple, drawn with ``rng``."""
    m, z = INTENTS[intent], INTENSITIES[intensity]
    combos = [(s, p, t) for s in SITUATIONS[m] for p in PLANS[m] for t in MODIFIERS[z]]
    pick = rng.choice(len(combos), size=min(count, len(combos)), replace=False)
    out = []
    for i in pick:
        situation, plan, template = combos[i]
        out.append(f"{situation} {template.format(p=plan, P=plan[0].upper() + plan[1:])}")
    return tuple(out)
