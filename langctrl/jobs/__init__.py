"""The jobs that run langenv's parts from the command line (``langctrl play``, ``exercise``,
``speech``, ``robot``): each module a ``build_parser()`` and a ``main(argv)``, above every part
of ``langenv`` (the reusable logic stays in the parts). Importing this package loads no job."""
