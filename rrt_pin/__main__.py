"""``python -m rrt_pin``: the rrt-pin command line."""

from rrt_pin.cli import main

raise SystemExit(main())
