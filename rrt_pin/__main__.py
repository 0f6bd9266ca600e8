"""``python -m rrt_pin``: the rrt-pin command line."""

from rrt_pin.cli.app import main

raise SystemExit(main())
