from jgrounding.cli import main

raise SystemExit(main())
