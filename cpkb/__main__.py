from cpkb.cli import main

raise SystemExit(main())
