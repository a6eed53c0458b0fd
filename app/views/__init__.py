"""What both the dashboard and the export draw: scene framing, the arena and graph views, graph
layout, the genome's shape and geometry helpers.

Layering: `app.views` imports the lab core (`app`, `app.store`), `sim` and `gnp`, never
`app.dashboard` nor `app.export`; both of those import it (tests/app/design/test_layers.py).
"""
