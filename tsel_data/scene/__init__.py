"""What a scene is before it is rendered: the scene recipe, the plain data the planner
writes and the renderer reads (``recipe``: sources, room, array, noise, query plan, and
the machine paths a plan resolves), the distributions config values draw from
(``distributions``), and the query relations decided on the rendered truth (``queries``).

Import order: ``distributions``, ``queries``, ``recipe`` (none imports another).
"""
