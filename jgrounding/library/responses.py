"""Open-vocabulary response texts that each (intent, intensity) tuple was reduced from (Sec. III-C.1).

The paper generates them with an MLLM over offline cue-history instances; we generate them from
templates with variety — situation x response plan x intensity modifier — phrased as an MLLM would
write a social response plan. The ``Raw`` ablation baseline conditions on their text embeddings.
The evaluation set for the text -> tuple reducer is written separately and never built from these.

Held-out pairs (one per tuple) take their texts from their own pool — :data:`HELDOUT_SITUATIONS`,
:data:`HELDOUT_PLANS`, :data:`HELDOUT_MODIFIERS`, written separately and never used for a training
pair — so the Raw condition is tested on new phrasing, as in the paper, where every held-out pair has
its own MLLM response.
"""

from __future__ import annotations

import numpy as np

from jgrounding.vocabulary import INTENSITIES, INTENTS

SITUATIONS = {
    "greeting": [
        "The user just walked in and waved at me.",
        "A visitor approached and said hello.",
        "The user smiled at me from across the room.",
        "Someone new sat down in front of me.",
    ],
    "farewell": [
        "The user is packing up to leave.",
        "The user said they have to go now.",
        "The session is ending and the user stood up.",
        "The visitor waved goodbye at the door.",
    ],
    "comforting": [
        "User seems sad; their voice is shaky.",
        "The user sighed and looked down at the floor.",
        "The user mentioned a rough day and sounds tired.",
        "The user is tearful after a phone call.",
    ],
    "attentive_listening": [
        "The user is telling me a long story.",
        "The user started explaining a problem.",
        "The user is speaking softly about their plans.",
        "The user asked me to listen for a moment.",
    ],
    "curiosity": [
        "The user placed an unfamiliar object on the table.",
        "The user hid something behind their back.",
        "A new toy appeared near me.",
        "The user asked what I think of this strange gadget.",
    ],
    "embracing": [
        "The user opened their arms toward me.",
        "The user asked for a hug.",
        "The user is celebrating good news and leans in close.",
        "The user looks lonely and reaches out.",
    ],
    "withdrawal": [
        "The user flinched when I moved closer.",
        "The user said I am too close.",
        "The user raised a hand to keep distance.",
        "The user looks startled by my movement.",
    ],
    "coiling": [
        "A loud noise startled everyone in the room.",
        "The user teased me about being shy.",
        "The user is scolding me gently.",
        "Several strangers are crowding around me.",
    ],
    "playful_swing": [
        "The user is laughing and playing music.",
        "The user invited me to play a game.",
        "Children are giggling around me.",
        "The user is dancing in front of me.",
    ],
    "nodding": [
        "The user asked if I understood.",
        "The user made a point I agree with.",
        "The user asked whether we should continue.",
        "The user is checking that I followed the steps.",
    ],
    "refusing": [
        "The user offered me something I should not take.",
        "The user asked me to do something unsafe.",
        "The user asked if I want more candy and I should decline.",
        "The user suggested touching the stove.",
    ],
    "beckoning": [
        "The user is standing far away and looks unsure.",
        "The user hesitates at the doorway.",
        "I want the user to come see something.",
        "A shy child is watching me from a distance.",
    ],
    "pointing": [
        "The user asked where the exit is.",
        "The user is looking for their keys, which are on the shelf.",
        "The user asked which way to the kitchen.",
        "The user wants to know where to sit.",
    ],
    "celebrating": [
        "The user just won the game!",
        "The user announced they passed their exam.",
        "The user shared wonderful news about a new job.",
        "The team scored and the user cheered.",
    ],
    "resting": [
        "The user is reading quietly.",
        "It is late and the room is calm.",
        "The user asked me to relax for a while.",
        "Nobody is interacting with me right now.",
    ],
    "offering": [
        "The user looks like they need a tissue.",
        "The user asked me to hand over the cup.",
        "The user is reaching for the remote next to me.",
        "The user wants the flower I am holding.",
    ],
}

PLANS = {
    "greeting": ["greet them back with a wave", "say hello and wave toward them", "welcome them with a friendly wave"],
    "farewell": [
        "wave goodbye and then settle down",
        "see them off with a slow farewell wave",
        "bid them goodbye and lower the trunk",
    ],
    "comforting": [
        "respond calmly and offer a gentle touch",
        "approach slowly and pat their shoulder",
        "comfort them with a soft stroke",
    ],
    "attentive_listening": [
        "lean in and listen attentively",
        "stay still, lean closer and show I am listening",
        "tilt toward them and keep quiet attention",
    ],
    "curiosity": ["explore it curiously with the tip", "sniff around it from side to side", "probe it with interest"],
    "embracing": ["wrap around them in a hug", "give them a warm embrace", "curl around them like a hug"],
    "withdrawal": [
        "back away and give them space",
        "retreat and bend away from them",
        "pull back to a respectful distance",
    ],
    "coiling": ["curl up shyly", "coil the trunk inward to self-soothe", "tuck in and make myself small"],
    "playful_swing": [
        "swing playfully from side to side",
        "sway along in a bouncy, playful way",
        "do a loose playful swing",
    ],
    "nodding": ["nod to show agreement", "bob up and down to acknowledge", "give an approving nod"],
    "refusing": [
        "shake the trunk to say no",
        "decline by shaking side to side",
        "refuse with a clear head-shake motion",
    ],
    "beckoning": ["beckon them to come closer", "curl the tip back to invite them over", "wave them over toward me"],
    "pointing": [
        "point toward it and hold",
        "extend the trunk toward the right direction",
        "indicate the place by pointing",
    ],
    "celebrating": [
        "celebrate with an energetic trumpet flourish",
        "rise up high and cheer with them",
        "join the celebration with lively flourishes",
    ],
    "resting": ["relax and stay quiet", "droop and rest calmly", "settle into a calm resting pose"],
    "offering": [
        "reach out and hand it over",
        "offer it to them with the tip curled up",
        "extend toward them to give it",
    ],
}

MODIFIERS = {
    "subtle": [
        "Respond subtly: {p}, barely moving.",
        "Keep it small and gentle: {p}, just a little.",
        "Quietly {p}, slightly and slowly.",
    ],
    "moderate": ["Respond calmly: {p}.", "{P} at a comfortable, moderate pace.", "In a relaxed way, {p}."],
    "pronounced": [
        "Clearly {p}, with a noticeable motion.",
        "Respond expressively: {p}, reaching well toward them.",
        "Make it obvious: {p} with a big, lively movement.",
    ],
    "emphatic": [
        "Enthusiastically {p}, with full energy!",
        "Respond emphatically: {p} as strongly as possible!",
        "Go all out and {p}, fast and wide!",
    ],
}


HELDOUT_SITUATIONS = {
    "greeting": [
        "A neighbour I have not seen for weeks pops her head around the corner.",
        "Grandpa arrives for his weekly visit, grinning.",
    ],
    "farewell": [
        "Coat on and bag in hand, my friend heads for the exit.",
        "Visiting hours are over; the nurse leads the guest out.",
    ],
    "comforting": [
        "My friend's dog died this morning and he keeps wiping his eyes.",
        "She failed the driving test again and slumps in the chair.",
    ],
    "attentive_listening": [
        "He begins describing his childhood village in detail.",
        "A girl whispers that she has a secret to share.",
    ],
    "curiosity": [
        "A strange humming box was left on the floor beside me.",
        "Someone unwrapped a parcel full of odd shapes.",
    ],
    "embracing": [
        "After a long trip abroad, my owner rushes over, arms wide.",
        "A toddler toddles up and throws both arms out.",
    ],
    "withdrawal": [
        "An elderly man shrinks back whenever I shift position.",
        "She waves her palm at me: stop, not now.",
    ],
    "coiling": [
        "Everyone at the party turns to stare at me at once.",
        "Thunder cracks outside and the lights flicker.",
    ],
    "playful_swing": [
        "The kids put on a silly song and start hopping around.",
        "A puppy chases its tail right next to me.",
    ],
    "nodding": ["She wonders aloud if tomorrow at nine works for me.", "He double-checks that the plan sounds right."],
    "refusing": ["A boy dares me to knock the vase off the table.", "Someone wants me to grab a hot pan."],
    "beckoning": [
        "A nervous new student lingers by the far wall.",
        "My friend is stuck at the gate, not sure whether to enter.",
    ],
    "pointing": [
        "A delivery driver asks which door is the right one.",
        "Grandma cannot find her glasses; they lie on the windowsill.",
    ],
    "celebrating": ["Our team just took the championship trophy!", "She got the scholarship she dreamed of!"],
    "resting": [
        "The house is dark and everybody has gone to bed.",
        "A long afternoon with nothing happening drags on.",
    ],
    "offering": ["My friend is shivering and the blanket is right by me.", "The child keeps eyeing the apple I hold."],
}
HELDOUT_PLANS = {
    "greeting": ["lift up and say hi with a swaying hello", "hail her warmly with a raised trunk"],
    "farewell": ["wish them safe travels, swaying down to a tucked rest", "send a parting sway and fold up"],
    "comforting": ["ease over and soothe him with a soft touch", "drift close and reassure her tenderly"],
    "attentive_listening": ["bend forward and hang on every word", "incline quietly toward her, all ears"],
    "curiosity": ["nose around the thing, exploring it", "inspect it inquisitively with my tip"],
    "embracing": ["enfold them in a cuddle", "gather the child into a gentle wrap"],
    "withdrawal": ["shrink away to leave him room", "draw back out of her way"],
    "coiling": ["roll myself up bashfully", "wind inward and hide"],
    "playful_swing": ["sway merrily to the rhythm", "rock loosely to and fro for fun"],
    "nodding": ["signal yes with a bob", "dip up and down in assent"],
    "refusing": ["wag a firm no", "turn it down with a sideways shake"],
    "beckoning": ["invite them over with a curling gesture", "coax her nearer with a summoning curl"],
    "pointing": ["aim my trunk at the spot and keep it there", "direct them by stretching toward the place"],
    "celebrating": ["rejoice with a triumphant burst", "toot and flourish in triumph"],
    "resting": ["hang limp and unwind", "doze with my trunk slack"],
    "offering": ["pass it across to them", "present it held aloft on my tip"],
}
HELDOUT_MODIFIERS = {
    "subtle": ["Very faintly, {p}; hardly any motion.", "With restraint, {p} — tiny and unhurried."],
    "moderate": ["Without fuss, {p}.", "Evenly and steadily, {p}."],
    "pronounced": ["Plainly {p}, a broad visible gesture.", "With conviction, {p}, large and clear."],
    "emphatic": ["Wildly {p} — maximum vigor!", "Passionately {p}, huge and quick!"],
}
assert set(HELDOUT_SITUATIONS) == set(HELDOUT_PLANS) == set(INTENTS)


def response_texts(
    intent: int, intensity: int, count: int, rng: np.random.Generator, heldout: bool = False
) -> tuple[str, ...]:
    """``count`` distinct response texts for the tuple, drawn with ``rng`` (from the held-out pool
    when ``heldout``)."""
    m, z = INTENTS[intent], INTENSITIES[intensity]
    situations, plans, modifiers = (
        (HELDOUT_SITUATIONS, HELDOUT_PLANS, HELDOUT_MODIFIERS) if heldout else (SITUATIONS, PLANS, MODIFIERS)
    )
    combos = [(s, p, t) for s in situations[m] for p in plans[m] for t in modifiers[z]]
    pick = rng.choice(len(combos), size=min(count, len(combos)), replace=False)
    out = []
    for i in pick:
        situation, plan, template = combos[i]
        out.append(f"{situation} {template.format(p=plan, P=plan[0].upper() + plan[1:])}")
    return tuple(out)
