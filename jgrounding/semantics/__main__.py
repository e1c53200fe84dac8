from jgrounding.semantics import main

raise SystemExit(main())
