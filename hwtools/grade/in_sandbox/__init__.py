"""What runs inside the sandbox: the grader copies this folder, whole, into every kit it runs, as
the package ``_hwgrade`` beside the kit's ``hwlib/``.

* ``worker.py``: the entry point of every sandboxed process (mounted alone as ``/grader/worker.py``);
* ``runtime.py``: its loop, as a student's worker or as the reference server;
* ``probes.py``: what a check calls in the kit, and the schema of each answer;
* ``served.py``: which other TODOs' functions a run may call on the trusted side (the proxies);
* ``served_env.py``: ``gym.make``'s CartPole, its resets and steps answered on the trusted side;
* ``channel.py``: the message format (npz behind a length, read strictly; never pickle).

Nothing here is trusted, and nothing here imports anything outside this folder (the standard
library, numpy, and, inside functions, the kit under test and its gymnasium):
``tests/test_imports.py`` proves it. The trusted side imports the shared pieces (the message
format, the served table and its checks, the probes' schemas and input builders) from here.
"""
