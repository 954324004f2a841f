"""The ``lsindy`` subcommands, one module each: ``add_to(subparsers)`` declares the options,
``run(args)`` does the work (options checked before any heavy work).  ``lsindy_cas.cli`` assembles them."""
