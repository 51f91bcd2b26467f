"""What a scene is before it is rendered: the scene recipe, the plain data the planner
writes and the renderer reads (``recipe``: sources, room, array, noise, query plan, and
the machine paths a plan resolves), the distributions config values draw from
(``distributions``), the query relations decided on the rendered truth (``queries``), and
a receiver's microphones as built for one scene (``hardware``); and what is said about a
scene: a source's motion class (``motion``), the spatial vocabularies (``vocabularies``),
the spatial questions decided on the truth (``questions``) and the tables of
docs/spatial-language.md (``language_doc``).

Import order: ``distributions``, ``queries``, ``hardware``, ``recipe`` (it holds
``hardware``'s plain data), ``motion``, ``vocabularies`` (no other imports another);
``questions`` (motion, queries, vocabularies); ``language_doc``.
"""
