"""The kit's machinery: students need not read this.

What makes your plain code fast, checks what it is given, and draws the notebooks' widgets; the
homework itself is in the files one folder up.

| module            | what it does                                                                 |
|-------------------|------------------------------------------------------------------------------|
| ``todos``         | the handout's TODO table, and ``TodoNotDone``, the error a TODO's starting code raises |
| ``validation``    | the checks every public function of ``hwlib`` makes at its door              |
| ``batch``         | runs your training code with the episodes it asks for played together (``Session``) |
| ``replay``        | record, then replay: how a run learns which episodes a call of your code asks for |
| ``episodes``      | plays many CartPole episodes at once (the kit's NumPy port of CartPole's step), checked against your policy's ``__call__`` |
| ``progress``      | the progress bar of the long cells                                           |
| ``reuse``         | the learning-rate sweep's result, kept for the next run of the same code (``reuse_stored=True``) |
| ``latest_only``   | redraw only the latest: the slider panel's and the landscape's redraws        |
| ``panel_controls``| the slider panel's small front-end part (``panel_controls.js``)               |
"""
