"""The leaf package: zenoh sessions, key expressions, message types, codecs and link faults.

Nothing here imports from ``sim``, ``vehicle`` or ``groundstation``.
"""
