"""experiments.ship: each step count is served by its best (checkpoint, guidance), one guidance per checkpoint."""

from experiments import ship

RF, MF, SC = ship.DEFAULT, ship.MEANFLOW, ship.SHORTCUT


def test_each_s_gets_its_winner_with_one_guidance_per_checkpoint():
    scores = {  # (S, checkpoint, w) -> score
        (50, RF, 0.0): 0.90,
        (50, RF, 0.5): 0.95,
        (50, MF, 0.0): 0.99,  # the default serves the largest S
        (1, RF, 0.5): 0.2,
        (1, RF, 0.0): 0.5,
        (1, MF, 0.0): 0.8,
        (1, MF, 0.5): 0.3,
        (1, SC, 1.0): 0.1,
        (2, RF, 0.5): 0.85,
        (2, MF, 0.0): 0.8,
        (2, MF, 0.5): 0.9,  # MF is fixed at w = 0 by S = 1: RF wins
    }
    table = [(s, n, w, {"score": sc}, sc) for (s, n, w), sc in scores.items()]
    served, fixed = ship.assign(table, (1, 2, 50))
    assert {s: v[:2] for s, v in served.items()} == {50: (RF, 0.5), 1: (MF, 0.0), 2: (RF, 0.5)}
    assert served[1][2] == {"score": 0.8}
    assert fixed == {RF: 0.5, MF: 0.0, SC: 1.0}  # SC serves nothing: its best w at the smallest S
