from jgrounding.apps.cli import main

raise SystemExit(main())
