"""The top floor's experiments, one module per paper (``vision_slam``, ``cooperative``), the
centralized reference run next to the pure world, and the in-process harness the tests and
benchmarks share. May import every package; nothing below it imports it."""
