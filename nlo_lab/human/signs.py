"""The old import path of the sign vocabulary, which now lives in :mod:`nlo_lab.corpus.signs`.

Notebook 02 of earlier versions imports ``HANDSHAPES`` from here, and ``nlo-lab lab``
never overwrites a learner's copy.
"""

from nlo_lab.corpus import (
                            CONTACT_LOCATIONS,
                            HANDSHAPES,
                            HELD_OUT_PAIRS,
                            LOCATIONS,
                            MOVEMENTS,
                            PALMS,
                            PATTERNS,
                            Sign,
                            handshape,
                            is_test_combination,  # fmt: skip
                            location_normal,
                            location_point,
                            minimum_jerk,
                            movement_path,
                            random_sign,
)

__all__ = ["HANDSHAPES", "LOCATIONS", "CONTACT_LOCATIONS", "PALMS", "MOVEMENTS", "PATTERNS", "HELD_OUT_PAIRS", "Sign", "minimum_jerk",
           "handshape", "location_point", "location_normal", "movement_path", "is_test_combination", "random_sign"]  # fmt: skip
