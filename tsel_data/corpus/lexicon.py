"""The sound-event vocabulary of captions: lemmas, synonyms and broader terms.

``scene.similarity = "lexicon"`` (tsel_data.corpus.captions) compares captions as sets of
*concepts*: every content word is lemmatised ("speaking", "speaks", "spoke" -> "speak";
"men" -> "man"; "cars" -> "car"), mapped to its synonym group ("talk", "speech",
"narrate", "voice" -> "speak"; "male", "guy" -> "man") and joined by the groups it
belongs to ("car" -> "vehicle"; "bark" -> "dog"), so "A man is speaking" and "A male
voice narrates" are the same two concepts. The table holds the events AudioCaps and
Clotho captions name most (chosen from the words of the 57k AudioCaps captions); a word
outside it stands for itself, lemmatised. Everything is in this file: nothing is
downloaded, no dictionary is read.
"""
from __future__ import annotations

import re

_WORD = re.compile(r"[a-z]+")

# Words that say how, how often or how loud, or that every caption could hold: they
# never tell two sounds apart, so they are not concepts.
FILLER = frozenset("""
a an the and or but nor of in on at to from by with without as is are was were be being been am
it its this that these those there here then than while whilst during followed follow after before
into onto over under up down out off some someone's something very far nearby near distance distant
background foreground loud loudly quiet quietly softly soft faint faintly several multiple many few
frequently frequent roughly smoothly kind sort well lot lots meanwhile effect environment single
white static row pitch pitched echo outside outdoors indoors inside concurrent nonstop vocalize vocalization
work operate function use blow run going
more most much other another again once twice thrice times time one two three four five series
small large big little high low heavy heavily light lightly hard hardly fast quick quickly slow
slowly rapid rapidly brief briefly short long continuous continuously constant constantly steady
steadily repeated repeatedly repetitive intermittent intermittently occasional occasionally
sudden suddenly periodically periodic consistent consistently ongoing gentle gently strong
strongly sharp sharply slight slightly mid medium moderate moderately deep loudness volume
sound sounds noise noises audio clip recording heard hear can also then just still some nearby
begin start stop continue occur end finish make give take get go come have do let keep seem
present various different same each every all both either any them they their
it we us our you your who whom which what where when how something somewhere anyone s
through around along across against past toward towards away back together closer louder
quieter nearer further farther briefly shortly like about between behind beside alongside amid
accompany accompanied accompanying along amongst among while themselves oncoming
""".split())

# word -> lemma, where the suffix rules below would go wrong
IRREGULAR = {
    "men": "man", "women": "woman", "children": "child", "people": "person", "persons": "person",
    "geese": "goose", "mice": "mouse", "feet": "foot", "teeth": "tooth", "oxen": "ox", "sheep": "sheep",
    "spoke": "speak", "spoken": "speak", "ran": "run", "flew": "fly", "flown": "fly", "sang": "sing",
    "sung": "sing", "rang": "ring", "rung": "ring", "blew": "blow", "blown": "blow", "fell": "fall",
    "fallen": "fall", "drove": "drive", "driven": "drive", "rode": "ride", "ridden": "ride",
    "shot": "shoot", "threw": "throw", "thrown": "throw", "struck": "strike", "broke": "break",
    "broken": "break", "made": "make", "came": "come", "went": "go", "gone": "go", "goes": "go",
    "does": "do", "did": "do", "gave": "give", "given": "give", "took": "take", "taken": "take",
    "began": "begin", "begun": "begin", "shook": "shake", "shaken": "shake", "swept": "sweep",
    "sped": "speed", "fed": "feed", "fought": "fight", "brought": "bring", "caught": "catch",
    "heard": "hear", "told": "tell", "said": "say", "says": "say", "sat": "sit", "stood": "stand",
    "left": "leave", "led": "lead", "lit": "light", "hit": "hit", "shut": "shut", "cut": "cut",
    "put": "put", "set": "set", "burst": "burst", "dug": "dig", "swam": "swim", "bit": "bite",
    "bitten": "bite", "ate": "eat", "eaten": "eat", "wrote": "write", "written": "write",
    "rose": "rise", "risen": "rise", "woke": "wake", "knelt": "kneel", "slid": "slide", "spun": "spin",
    "wound": "wind", "blowing": "blow", "dying": "die", "lying": "lie", "tying": "tie", "was": "be",
    "were": "be", "is": "be", "are": "be", "has": "have", "had": "have", "having": "have",
    "bus": "bus", "buses": "bus", "busses": "bus", "gas": "gas", "glass": "glass", "grass": "grass",
    "series": "series", "species": "species", "news": "news", "chaos": "chaos", "bass": "bass",
    "brass": "brass", "chorus": "chorus", "walrus": "walrus", "octopus": "octopus", "virus": "virus",
    "speed": "speed", "bleed": "bleed", "feed": "feed", "need": "need", "breed": "breed", "weed": "weed",
    "red": "red", "bed": "bed", "shed": "shed", "sled": "sled", "wed": "wed",
    "during": "during", "evening": "evening", "morning": "morning", "ceiling": "ceiling",
    "building": "building", "thing": "thing", "something": "something", "nothing": "nothing",
    "everything": "everything", "anything": "anything", "spring": "spring", "string": "string",
    "sing": "sing", "ring": "ring", "king": "king", "wing": "wing", "swing": "swing", "bring": "bring",
    "sting": "sting", "sling": "sling", "ding": "ding", "ping": "ping", "bling": "bling",
    "wings": "wing", "rings": "ring", "springs": "spring", "strings": "string", "dings": "ding",
    "pings": "ping", "swings": "swing",
    "ceilings": "ceiling", "buildings": "building", "things": "thing",
    "purring": "purr", "purrs": "purr", "purred": "purr", "whirring": "whir", "whirrs": "whir",
    "whirr": "whir", "whirred": "whir", "faucets": "faucet", "leaves": "leaf", "wolves": "wolf",
    "knives": "knife", "lives": "life", "hooves": "hoof", "shelves": "shelf", "calves": "calf",
    "oxes": "ox", "boxes": "box", "foxes": "fox", "axes": "axe",
    "opening": "open", "opened": "open", "happening": "happen", "listening": "listen",
    "becoming": "become", "coming": "come", "whimpering": "whimper", "whimpered": "whimper",
    "hovering": "hover", "flickering": "flicker", "fluttering": "flutter", "chattering": "chatter",
    "clattering": "clatter", "muttering": "mutter", "pattering": "patter", "sputtering": "sputter",
    "thundering": "thunder", "murmuring": "murmur", "murmured": "murmur", "whispering": "whisper",
    "whispered": "whisper", "shimmering": "shimmer", "stuttering": "stutter", "battering": "batter",
    "hammering": "hammer", "hammered": "hammer", "triggered": "trigger", "triggering": "trigger",
    "gathering": "gather", "wandering": "wander", "entering": "enter", "offering": "offer",
    "lowering": "lower", "powering": "power", "powered": "power", "answering": "answer",
    "engineering": "engineer", "cooing": "coo", "mooing": "moo", "booing": "boo", "wooing": "woo",
    "baaing": "baa", "peeing": "pee", "skiing": "ski", "seeing": "see", "fleeing": "flee",
    "traveling": "travel", "travelling": "travel", "signaling": "signal", "signalling": "signal",
    "vomiting": "vomit", "visiting": "visit", "limiting": "limit", "crediting": "credit",
    "riveting": "rivet", "carpeting": "carpet", "trumpeting": "trumpet", "buffeting": "buffet",
    "galloping": "gallop", "developing": "develop", "gossiping": "gossip", "whistling": "whistle",
    "trickling": "trickle", "bubbling": "bubble", "idling": "idle", "idled": "idle",
    "ticktocks": "ticktock", "tiktok": "ticktock", "lightning": "lightning", "creating": "create",
    "created": "create", "igniting": "ignite", "ignited": "ignite", "writing": "write", "biting": "bite",
    "exciting": "excite", "excited": "excite", "inviting": "invite", "uniting": "unite",
    "changing": "change", "changed": "change", "exchanging": "exchange", "arranging": "arrange",
    "ranging": "range", "mimicking": "mimic", "mimicked": "mimic", "panicking": "panic",
    "hiccuping": "hiccup", "hiccupped": "hiccup", "hiccupping": "hiccup", "signaled": "signal",
    "shoes": "shoe", "toes": "toe", "canoes": "canoe", "hoes": "hoe", "oboes": "oboe",
    "oncoming": "oncoming", "sniffing": "sniff", "breathing": "breathe", "soothing": "soothe",
    "bathing": "bathe", "teething": "teethe",
}

# Synonym groups: the first word names the concept, every word listed (as a lemma)
# stands for it. Then the broader concepts a concept also stands for.
SYNONYMS = """
speak: speak talk speech narrate narration narrator say converse conversation chat chatter babble communicate monologue
  lecture announce announcement announcer discuss discussion dialogue dialog preach sermon interview
  voice vocal speaker word address report reporter commentary commentator broadcast
  sentence utterance language
whisper: whisper murmur mumble mutter
shout: shout yell scream holler shriek exclaim
laugh: laugh laughter giggle chuckle snicker cackle
sing: sing song singer chant
cry: cry sob weep wail bawl
cough: cough hack
sneeze: sneeze
burp: burp belch
snore: snore
breathe: breathe breath pant gasp wheeze sniff
man: man male guy gentleman boy he him his
woman: woman female lady girl she her
child: child kid boy girl toddler youngster son daughter baby infant newborn
baby: baby infant newborn
person: person someone somebody adult human individual man woman child crowd audience
crowd: crowd audience spectator group
cheer: cheer whoop
applause: applause applaud clap
footstep: footstep step walk stomp tread shoe
car: car automobile sedan taxi
truck: truck lorry
motorcycle: motorcycle motorbike moped scooter dirtbike
engine: engine motor
vehicle: vehicle traffic car truck bus motorcycle engine van tractor
horn: horn honk
rev: rev accelerate acceleration
idle: idle
move: move drive pass zoom approach travel go fly roll cruise come
train: train locomotive railroad railway rail subway tram
aircraft: aircraft airplane plane jet airliner helicopter propeller
boat: boat motorboat speedboat ship yacht vessel
dog: dog puppy pup hound canine bark yap woof yelp yip growl
bark: bark yap woof yelp yip
cat: cat kitten kitty meow mew purr
meow: meow mew
bird: bird birdsong chirp tweet twitter cheep warble songbird pigeon dove duck goose crow rooster
  chicken hen owl seagull gull
chirp: chirp tweet twitter cheep warble
pigeon: pigeon dove coo
duck: duck quack
rooster: rooster chicken hen cluck crow cockerel
horse: horse pony neigh whinny clop trot gallop
sheep: sheep lamb bleat baa
goat: goat
pig: pig hog swine oink boar snort
cow: cow cattle bull moo
frog: frog toad croak
animal: animal dog cat bird horse sheep goat pig cow frog insect
insect: insect bug bee mosquito cricket cicada swarm
water: water liquid stream river brook creek flow trickle pour gurgle splash slosh drip faucet sink
  fountain waterfall wave ocean sea surf rain toilet flush
stream: stream river brook creek flow trickle gurgle
splash: splash slosh splatter
ocean: ocean sea wave surf tide
rain: rain raindrop drizzle downpour
toilet: toilet flush
wind: wind breeze gust
microphone: microphone mic
thunder: thunder thunderstorm storm lightning
fire: fire flame burn
music: music melody tune instrument piano guitar drum violin orchestra band musical
bell: bell chime ding dong toll ring
clock: clock tick tock ticktock
siren: siren emergency ambulance police firetruck
alarm: alarm
phone: phone telephone cellphone ringtone
door: door
knock: knock tap thump thud pound bang hit strike
gun: gun gunshot gunfire shoot rifle pistol
explosion: explosion explode blast boom pop firework firecracker
drill: drill
saw: saw chainsaw
type: type keyboard typewriter keystroke
fry: fry sizzle frying grease oil
spray: spray aerosol
hiss: hiss steam
hum: hum drone whir buzz
beep: beep bleep
click: click clack clink
rustle: rustle crinkle crumple crackle
scrape: scrape scratch grind rub sand
squeak: squeak creak
"""


def _groups() -> dict[str, frozenset[str]]:
    """lemma -> the concepts it stands for: its groups, and the groups that list those
    (a group named in another is a narrower term: "male" -> man -> person)."""
    direct: dict[str, set[str]] = {}
    for block in re.split(r"\n(?=\S)", SYNONYMS.strip()):
        head, _, words = block.partition(":")
        for w in words.split():
            direct.setdefault(w, set()).add(head.strip())
    out = {}
    for w, heads in direct.items():
        closed, todo = set(), list(heads)
        while todo:
            h = todo.pop()
            if h not in closed:
                closed.add(h)
                todo += direct.get(h, ())
        out[w] = frozenset(closed)
    return out


CONCEPTS = _groups()
NAMED = frozenset(h for heads in CONCEPTS.values() for h in heads)
# A word outside the table is mostly a modifier or an object ("rhythmic", "wooden",
# "sleeper"), rarely the sound itself; a broad term says little on its own ("a man
# speaks" and "a woman laughs" are both a person): both count half as much.
UNNAMED_WEIGHT = 0.5
BROAD = frozenset({"person", "vehicle", "water", "animal"})
_VOWELS = "aeiou"


def weight(concept: str) -> float:
    """How much a concept counts in the ``lexicon`` similarity: 1 for the table's events
    and sources, half for broad terms and words the table does not name."""
    return 1.0 if concept in NAMED and concept not in BROAD else UNNAMED_WEIGHT


def lemma(word: str) -> str:
    """The dictionary form of a caption word: plural nouns singular, verbs bare
    ("barking", "barks", "barked" -> "bark"; "idling" -> "idle"; "cries" -> "cry")."""
    if word in IRREGULAR:
        return IRREGULAR[word]
    if len(word) <= 3:
        return word
    if word.endswith("ies") and len(word) > 4:
        return word[:-3] + "y"
    if word.endswith("ied") and len(word) > 4:
        return word[:-3] + "y"
    for suffix in ("ing", "ed"):
        if word.endswith(suffix) and len(word) - len(suffix) >= 3:
            return _restore(word[: -len(suffix)])
    if word.endswith(("sses", "zzes", "ches", "shes", "xes", "oes")):
        return word[:-2]
    if word.endswith("s") and not word.endswith(("ss", "us", "is")):
        return word[:-1]
    return word


def _restore(stem: str) -> str:
    """A verb stem with its suffix cut, made whole: a doubled final consonant undone
    ("revv" -> "rev"), a silent e put back ("rustl" -> "rustle", "mak" -> "make")."""
    if stem.endswith("y") or len(stem) < 2:
        return stem
    last, before = stem[-1], stem[-2]
    if last == before and last not in _VOWELS + "lsfz":
        return stem[:-1]
    if last == "l" and before not in _VOWELS + "lrw":  # rustl, gurgl, whistl
        return stem + "e"
    if last in "vcu" or (last in "zs" and before in _VOWELS) or stem.endswith(("rs", "rg", "dg", "uat")):
        return stem + "e"  # mov, slic, continu, sneez, releas, convers, submerg, punctuat
    single = before in _VOWELS + "y" and (len(stem) < 3 or stem[-3] not in _VOWELS)
    if single and last not in "wxyrn" and not stem.endswith(("en", "on", "el", "er", "et", "it", "om", "or")):
        return stem + "e"
    if single and last in "rn" and len(stem) <= 4:  # snor, blar, whin, ston
        return stem + "e"
    return stem


def concepts(caption: str) -> frozenset[str]:
    """The concepts of a caption: its content words' lemmas, each replaced by the
    concepts of its synonym groups when the table knows it."""
    out: set[str] = set()
    for w in _WORD.findall(caption.lower()):
        if w in FILLER:
            continue
        lem = lemma(w)
        if lem in FILLER:
            continue
        out |= CONCEPTS.get(lem, {lem})
    return frozenset(out)
