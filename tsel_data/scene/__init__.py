"""What a scene is before it is rendered: the scene recipe, the plain data the planner
writes and the renderer reads (``recipe``: sources, room, array, noise, query plan, and
the machine paths a plan resolves), the distributions config values draw from
(``distributions``), the query relations decided on the rendered truth (``queries``), and
a receiver's microphones as built for one scene (``hardware``).

Import order: ``distributions``, ``queries``, ``hardware``, ``recipe`` (``recipe`` holds
``hardware``'s plain data; no other imports another).
"""
