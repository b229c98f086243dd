"""``python -m upsr``: the ``upsr`` command line (as the ``upsr`` script)."""

from upsr.apps.cli.main import main

if __name__ == "__main__":
    main()
