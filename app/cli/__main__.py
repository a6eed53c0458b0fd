"""`python -m app.cli`: gnp-lab."""

from app.cli.main import main

raise SystemExit(main())
