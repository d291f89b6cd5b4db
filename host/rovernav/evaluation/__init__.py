"""Evaluation: what the simulator's runs are measured on and how they are judged.

    arenas   `rovernav arenas`: scenario files drawn from families of arenas, labelled with a
             difficulty and whether they can be solved
    trials   `rovernav trials`: many missions on many arenas, in parallel, scored, tabled and gated

It stands above the simulator (rovernav.sim, the world it runs missions in): evaluation imports
sim, never the other way round.
"""
