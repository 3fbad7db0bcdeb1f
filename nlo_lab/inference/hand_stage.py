"""The hand stage: after the latent optimisation, the hands' joints alone, on the same objective.

The decoder maps one latent to the whole robot, so the latent optimisation moves the fingers
only as far as the decoder's hands reach, and 100 steps shared with the arms leave them short
of the objective's best handshape (``benchmarks/hands.py`` measured it: docs/RESULTS.md,
"Handshapes"). The hand joints do not move the wrist, so this stage optimises them alone,
in joint space, on the same weighted objective (collision and smoothness included), the arms
kept where the latent optimisation put them:

``q_hand* = argmin_(q_hand in limits) sum_t L(D_t, K(q_arm,t, q_hand,t)) + w_smooth L_smooth``

Adam from the decoder's hands (warm start), every frame at once, the limits by clamping after
each step (projected gradient), the best point of the whole sequence kept (patience as the
latent optimisation's). Where the arm and wrist are scored (Table I) nothing changes.

Only the hands the clip shows move: a hand without a finger target in any frame has nothing to follow,
so its joints keep the latent optimisation's values bit for bit, its points stay the start's (the hand
chains map the seen hands alone) and its hand-term items are left out (they are masked to 0). Before,
such a hand moved with the others under the collision and smoothness terms alone (Adam's steps are
about ``lr`` whatever the gradient's size: on ``benchmarks/hands.py``'s recordings up to 0.27 rad, a
smoothing nothing scores); it still counts there as fixed capsules and a constant share of the
smoothness term, so the seen hand feels it as before. The seen hand's result is unchanged (at most
1.2e-6 rad apart on those recordings, float32 sums; the four measures and the retimed duration the same
to the printed digits), and the stage's time there drops by a fifth (refine_hands' thread time on the
pipeline's inputs, medians of 5: 2.19 -> 1.75 ms per frame, 2026-11-26 14:40 UTC, load 3.4): two of
their four clips never show the left hand. A
seen hand keeps moving in the frames that do not show it: the smoothness term carries it between the
frames that do (and leaving those frames out would save nothing: every frame is one batch).

The fast form (``FastPaths.hand_chains`` and ``written_gradient``, the pipeline's on the CPU) evaluates each
step's loss and gradient without an autograd graph (:class:`HandStageLoss`: FK of the hand chains, the numpy
terms and the smoothness term chained by hand; tested equal to autograd through the readable objective).
With the hands the clip shows alone, ``benchmarks/hands.py --no-write`` (2026-11-26 14:51-14:52 UTC, load
0.6-1.5, two alternating runs each) measured the stage at 1.65 / 1.99 ms per frame before both changes
(40b3537) and 1.05 / 1.06 ms after them (2723715); the whole retarget 4.21 / 4.95 -> 3.52 / 3.61 ms per frame,
every handshape measure the same.

It evaluates only what moves (:func:`compact_terms`): the residual rows and capsule pairs that reach a point below a
wrist, over the points they use (YuMi, both hands seen: 82 of 174); the arms' rows (ee, ori, elbow) are a constant
per frame, added to their terms. The hand chains are built once per plan and hands, and the result's loss and terms
after the speed clamp come from the same form without a gradient (:meth:`HandStageLoss.value`). On
``benchmarks/hands.py``'s four recordings, the latent optimisation's outputs kept and the stage alone timed (thread
time, medians of 5, two alternating runs each, 2026-11-26 17:07 UTC, load 1.5): 1.27 / 0.98 ms per frame before,
0.97 / 0.94 after, the hands bit for bit the same (every evaluation's loss, terms and gradient equal to the previous
form's there). What remains is per evaluation, not per frame, and the descent takes 60 of them on every clip but the
shortest. The hand terms on coordinate planes (:class:`~nlo_lab.objective.numpy_backend.HandTerms`), the moving points
one block of the compact terms' and FK's world axes written out (``MapPoints.gradient``) cut one from 1.22 / 1.78 /
1.62 ms (47 / 97 / 170 frames) to 1.05 / 1.42 / 1.36 ms (one :class:`HandStageLoss` call at the pipeline's start on
``benchmarks/hands.py``'s recordings, medians of 200, 2026-11-26 22:00-22:17 UTC, load 0.1-0.5; at 97 frames FK of
the hand chains 0.23, its gradient 0.19, the terms 0.38 and their backward 0.23, of which the hand terms 0.12 and
0.14), and the stage from 0.91 / 0.93 to 0.81 / 0.82 ms per frame (``benchmarks/hands.py --no-write``, two alternating
runs each, ef43779 against 2cd1863, 22:17-22:19 UTC, load 0.3-1.1; the whole retarget 2.56 / 2.65 -> 2.53 / 2.59 ms,
ratio to dex-retargeting's hand-frame 1.92 / 1.94 -> 1.94 / 1.94: the latent stage's time moves as much between runs),
q bit for bit the same. Bit for bit is the bar for a faster form here, not float32 rounding: the hand terms' backward
with one product in another orientation (``(3B, M) @ (M, U)`` for ``(U, M) @ (M, 3B)``: the last bits of the gradient)
moved q by up to 0.011 rad in 23 of 97 and 26 of 58 frames of two recordings (60 steps, the hinges, clamps and
best-of tracking carry a last-bit change into a different path). That rules out what does not sum as the present form
does, and a numpy FK written out (torch's 4x4 products do agree bit for bit with it, but at 97
frames the written composition cost 157 against torch's 107 us, the points 69 against 67 us) and ``R p + t`` on
coordinate planes (52 against 57 us: no gain).

Fewer evaluations cost the handshape (2026-11-26 17:05-17:15 UTC, the same recordings and starts; wrist->tip / thumb
/ base->tip [deg] / pinch r, the retimed duration summed over the four clips; now 17.16 / 25.24 / 34.13 / 0.807,
23.92 s): Adam 40 steps of 0.025 rad 17.27 / 25.05 / 34.48 / 0.809, 24.32 s; 30 of 0.025 17.35 / 25.13 / 34.88 /
0.810; the step decaying geometrically, 30 steps 0.04 -> 0.01 17.38 / 25.67 / 35.02 / 0.801, 40 steps 0.03 -> 0.01
17.35 / 25.35 / 34.85 / 0.806; Rprop 20 steps (first 0.02, at most 0.05) 17.32 / 25.47 / 34.70 / 0.818. More, smaller
steps gain on every measure (100 of 0.02, patience 100: 17.10 / 24.73 / 33.86 / 0.809, 23.66 s) at twice the time.
A second-order step does not take larger ones here: a Levenberg-Marquardt prototype (each frame's Hessian block of
the terms by finite differences of this gradient, every hand joint's perturbation in one batched evaluation; the
smoothness term's Gauss-Newton, block-tridiagonal, solved banded; the joints held at a bound out of the step) found
its quadratic model valid only for steps up to about 0.02-0.05 rad, Adam's own scale (a 0.13 rad step it predicted
to lower the 97-frame clip's mean loss raised it by 900): the normalised directions, the chord near its minimum and
the hinges bend the objective within a few hundredths of a radian. Twelve iterations (25 evaluations and 12 batched
ones) took that clip's mean loss from 8472 to 7834, Adam's 60 steps to 7244.

The start is a local optimum's basin: on ``benchmarks/hands.py``'s recordings the decoder leaves the ring
and little fingers curled at their upper limit in most hand-frames, where their wrist->fingertip
direction would be best half open, and between the two the error rises first (measured 2026-11-26 on a
grid of each finger joint). A search of each hand joint's range, frame by frame, before Adam finds the
objective's better optimum: wrist->tip 16.1° without the speed clamp, 16.7° with it, against 17.05°; but
there the thumb measure and the pinch are worse (30.0°, r 0.76 without the clamp; 29.2°, 0.78 with it;
dex-retargeting 27.8°, 0.79): at its optimum this objective gives the fingertips' directions more than the
thumb's, so the stage keeps the decoder's start. The capsules are not what holds the thumb: over every
third hand-frame, the thumb's best wrist->tip direction error with no capsule pair penetrating is 11.6° (no
overlap by the URDF's geometry: 11.2°, collisions allowed: 10.8°), the stage's 13.5°.

The speed clamp, not the start, is what binds (``benchmarks/hands_frontier.py``, 2026-11-26 14:30 UTC, load 4.0, the
latent optimisation's 40 Rprop steps: an exhaustive search over grids of each finger's joint, 48 values, and the
thumb's two, 24 x 24, the capsule pairs of a hand as constraints, the cost the measures themselves). Frame by frame
the best handshapes reach wrist->tip 16.09° (thumb 26.5°, base->tip 30.4°, pinch r 0.77; 15.5° with the thumb
weighed less), free of collision, but they jump between frames: held to the start's speed they are at 17.2°. Over
the whole trajectory, every step within the clamp's caps (dynamic programming), the search reaches wrist->tip /
thumb / base->tip / pinch r 16.73 / 26.4 / 32.5 / 0.78, or 16.22 / 29.0 / 32.5 / 0.77 with the thumb and base->tip
weighed less, and this stage from there ends at 16.66-16.82° with the pinch at 0.77-0.78 (from the latent
optimisation's hands: 17.16°, 0.81). Within the clamp, none of these trajectories of the 6-actuator hand gets
wrist->tip below dex-retargeting's 16.57° with the thumb measure and the pinch still ahead of its (27.8°, 0.79): a
start search trades the thumb and the pinch for the wrist->tip direction.
Weighing the pinch more does not open a way either (``benchmarks/hands_frontier.py --weights 1,0.2,0.5,0.5
1,0.2,0.5,1 1,0.3,0.3,1 1,0.1,0.3,1.5 --stage``, 2026-11-26 21:44 UTC, load 0.7-1.1): the searches' pinch r rises to
0.85-0.89 but their thumb measure to 30-41°, and this stage from their hands ends at wrist->tip 16.58-16.82°, thumb
27.2-29.4°, pinch r 0.77-0.78, behind dex-retargeting's 0.79 again. Nor do the stage's own weights and clamp move
wrist->tip far from where the start's basin holds it (``retarget`` on the same recordings, all else default; wrist->tip
/ thumb / base->tip [deg] / pinch r, 21:45-21:47 UTC): ``tip_dir`` 6000 17.10 / 24.46 / 35.67 / 0.807, 8000 17.08 /
24.78 / 35.82 / 0.796; ``thumb`` 250 17.09 / 27.55 / 33.74 / 0.805; the clamp's caps 1.5x 16.99 / 25.45 / 33.43 / 0.807
(the retimed duration of the four clips 23.92 -> 27.36 s).
``benchmarks/hands_levers.py`` turns one lever at a time (2026-11-27 01:37-01:52 UTC, the same recordings; wrist->tip /
thumb / base->tip [deg] / pinch r). Per finger, wrist->tip is thumb / index / middle / ring / little 13.55 / 13.86 / 16.75
/ 19.54 / 22.09° against dex-retargeting's (unfiltered) 11.16 / 13.72 / 17.09 / 18.70 / 22.19°: the thumb holds 2.4° of
the 0.6° mean gap, the ring 0.8°. Weighing one finger's items or searching a start frame by frame moves along the frontier:
the thumb's ``tip_dir`` 3x 17.03 / 26.43 / 34.10 / 0.800; the index and middle joints searched before the stage (16
values each, by this objective; the clamp's caps still the latent optimisation's) 16.70 / 27.83 / 33.38 / 0.780, with
the thumb's ``tip_dir`` 3x, ``thumb`` 800 and the index pair's ``thumb_gap`` 4x 16.72 / 27.64 / 33.62 / 0.794; the pinch
and the thumb gap drawn to 0.6x the human's thumb-finger distance on top (the robot's spans 0.13-0.93 hand lengths where
the human's spans 0.07-1.61) 16.71 / 27.40 / 33.63 / 0.811; the clamp's caps 1.5x instead 16.42 / 27.85 / 32.83 / 0.783
(the clips 28.1 s against 24.1 s). An open index matches the wrist->tip direction and loses the thumb-index distance's
course, the pinch; searching all four fingers 16.81 / 28.70 / 33.82 / 0.774.

The ring is the lever that crosses. On the 170-frame clip the latent optimisation leaves it curled, 2.35° behind
dex-retargeting's, and neither the stage nor a frame-by-frame search leaves that basin within the clamp (17.19°).
Searched along the whole clip, every step within the clamp's caps (``path=ring``: dynamic programming over 16 values of
its joint by this objective), with the ring's ``tip_dir`` 3x, the other fingers' ``finger_dir`` 2x and ``thumb`` 650,
the four measures are 16.52 / 27.61 / 35.94 / 0.804, each ahead of dex-retargeting's 16.57 / 27.76 / 36.24 / 0.792 (the
ring 15.97°, the clips 24.20 s); the same weights without the search 17.31 / 25.37 / 34.03 / 0.806. It is not the
default, for three reasons: the margins (0.05° on wrist->tip) come from per-finger weights tuned on the benchmark's own
four recordings, and on held-out clips they trade instead (every clip of the synthetic corpus's test split that shows a
hand, 7942 hand-frames: 11.23 / 16.54 / 14.42 / 0.720 -> 11.06 / 15.36 / 15.28 / 0.690, where dex-retargeting's
unfiltered scores 12.85 / 17.42 / 11.04 / 0.609 and its filtered 13.12 / 19.44 / 15.02 / 0.511: the defaults and the
tuning alike ahead on three measures and behind on base->tip; ``benchmarks/hands_levers.py --corpus 25 --dex``,
2026-11-27 04:03 UTC); the open ring pays with its base->tip direction (the ring's
``tip_dir`` 5x instead: base->tip 36.59°, behind); and the stage has neither per-finger weights nor a search yet (the
benchmark's search evaluates the whole objective 16 times per joint and hand, too slow for the time target: it needs the
ring's own terms over a table of its joint's values).

The finger search (``search``, :attr:`OptimizeSettings.hand_search <nlo_lab.inference.OptimizeSettings.hand_search>`;
off by default until 2026-11-28, the pipeline's default since: the middle, ring and little fingers, below) is that
search in the stage, for every finger it names: before the descent each named finger's own joints
(:func:`finger_joints`), one at a time and each hand the clip shows, go to the path of least objective through
``grid`` values over the joint's limits, every step within the speed clamp's caps (:func:`searched_start`,
:func:`path_within_caps`); the table is the objective per frame without the smoothness term (the caps bound the
steps), from the same form of the objective the descent runs, and a joint keeps its start where the path costs more.
The search lets weights act that the start's basin otherwise holds (``benchmarks/hands_levers.py``, 2026-11-27
12:40-12:58 UTC, load below 1; wrist->tip / thumb / base->tip [deg] / pinch r, the clips' retimed duration): ``tip_dir``
8000 and ``thumb`` 800 alone 17.05 / 24.18 / 36.03 / 0.803, 24.10 s; with ``path=middle,ring,pinky`` 16.46 / 27.50 /
34.54 / 0.807, 24.04 s; the search alone at the default weights leaves the held-out corpus's measures within 0.2° and
0.003 of the defaults' (``--corpus 25``). With the index searched too the pinch falls to 0.76 (an open index matches its
wrist->tip direction and loses the thumb-index distance's course); ``tip_dir`` 10000, ``thumb`` 1000, ``finger_dir``
2000 16.38 / 27.33 / 34.32 / 0.801; a grid of 8 values misses the ring's open basin (16.94°). The handshape preset,
``HANDSHAPE_SEARCH`` with :meth:`LossWeights.handshape <nlo_lab.objective.LossWeights.handshape>` (``nlo-lab retarget
--handshape``), is the first of these in the library: ``benchmarks/hands.py`` measures it beside the defaults
(docs/RESULTS.md, "Handshapes": ahead of dex-retargeting on all four measures on the four recordings, by 0.1° on
wrist->tip; on the held-out corpus better than the defaults on three measures, worse on base->tip). It is not the
default: it was chosen on those same four recordings, the margins are narrow, it trades the base->tip direction on
held-out clips, and its search costs about 0.9 ms per frame. On four real recordings added to the benchmark after
that choice (``benchmarks/data/recordings/``, 2026-11-27 16:07 UTC) it is ahead of dex-retargeting on wrist->tip
(14.2° against 14.7°) and the thumb (30.9° against 33.7°), level on the pinch (0.76) and behind on base->tip (27.6°
against 26.7°), where the defaults are level on wrist->tip (14.8° against 14.7°) and ahead on the thumb and pinch.
A thumb that trades per handshape (``hands_levers.py``'s ``thumb-gate``: the thumb's wrist->tip direction left out
where its hand pinches, pinching frames asking the pinch; 2026-11-27 19:00-19:25 UTC) costs the thumb's own wrist->tip
direction on both groups (13.55 -> 14.46° on the preset's four, 5.91 -> 9.14° on the added four, only full pinches
gated): the relaxed hands MediaPipe sees hold the thumb near a fingertip most of the time (the right hand of
``holistic_both_hands_47f`` in 42 of 47 frames at an activation of 0.5), so the thumb's direction counts there too.
Searching the thumb with the preset and weighing the thumb gap and the base->tip directions more (``weight:tip_dir=8000
weight:thumb=800 setting:hand_search=thumb,middle,ring,pinky weight:thumb_gap=3000 weight:finger_dir=3000``) is ahead
of dex-retargeting on all four measures on the added recordings (14.63 / 31.17 / 26.57 / 0.856 against 14.73 / 33.75 /
26.66 / 0.757), behind on wrist->tip on the preset's four (16.67° against 16.57°) and, on the held-out corpus, worse
than the defaults on wrist->tip and the thumb (11.51 / 16.99 / 13.78 / 0.726 against 11.23 / 16.54 / 14.42 / 0.720).
The thumb's ``tip`` item (its scaled wrist->tip vector: dex-retargeting's whole objective) is what holds its direction,
not the direction item alone (``finger:tip=...``, 2026-11-27 22:02-22:30 UTC; the preset's four / the added four):
0.01x 17.32 / 25.15 / 34.28 / 0.808 and 14.83 / 28.19 / 26.82 / 0.841 (the thumb 14.33° and 6.27° against 13.55° and
5.91°); ``tip`` 0.01x for every finger 17.30 / 27.25 / 34.76 / 0.776 and 15.02 / 29.20 / 29.08 / 0.831. More of it
moves along the same frontier: 3x 16.99 / 25.95 / 33.74 / 0.808 and 14.38 / 30.70 / 26.78 / 0.793 (behind
dex-retargeting on wrist->tip on the first group by 0.42°, on base->tip on the second by 0.12°), 6x 17.03 / 26.74 /
34.31 / 0.795 and 14.24 / 31.32 / 26.81 / 0.769.

By default it never makes the robot slower: after the descent, each hand joint's step between consecutive
frames is clamped, frame by frame, to what leaves the retimed segment no longer than the start's
(:func:`step_caps`: its velocity limit times the time the retiming gives the start's segment,
``max(1/fps, max_k |Δq_k|/v_k)`` over all joints, :mod:`nlo_lab.inference.retime`), so the retimed
trajectory is never longer than the start's. Without a clamp the stage's hands stretched one real clip's
retimed duration from 2.9x to 3.5x (``benchmarks/motion.py``, 2026-11-26); the clamp at each hand joint's
own limit or start step, which this one replaced, cost the wrist->tip measure 0.25° on the hand
benchmark's recordings (17.77° against 17.52°, measured 2026-11-26): where the arm already slows a
segment down, the fingers may move as fast.

``slowdown`` (:attr:`OptimizeSettings.hand_slowdown <nlo_lab.inference.OptimizeSettings.hand_slowdown>`, 1 by
default) multiplies those caps, the search's and the clamp's: each retimed segment at most ``slowdown`` times the
start's. The clamp is this stage's own rule, not the robot's (retiming keeps any trajectory within the velocity
limits), and dex-retargeting has none: its hands, put on the arms of nlo_lab's default output and retimed alike,
make the robot take 29.05 s over the preset's first four recordings and 22.11 s over the four added after, where
nlo_lab's defaults take 24.12 s and 15.72 s (its filtered variant 18.42 s and 12.03 s; ``benchmarks/hands.py``'s
"robot time", 2026-11-28 00:45 UTC).
Given the time dex-retargeting's hands take, the clamp's caps 1.5x-2x move the frontier (``benchmarks/hands_levers.py
--recordings chosen|added``, 2026-11-28 00:28-00:44 UTC; the preset's four / the added four, wrist->tip / thumb /
base->tip [deg] / pinch r, robot time; dex-retargeting unfiltered 16.57 / 27.76 / 36.24 / 0.792 and 14.73 / 33.75 /
26.66 / 0.757): the defaults with ``caps=1.5`` 16.99 / 25.45 / 33.44 / 0.807, 27.53 s and 14.55 / 28.90 / 26.39 /
0.831, 17.61 s (ahead on all four on the added four, behind on wrist->tip on the first); the preset as it was
(``tip_dir`` 8000, ``thumb`` 800, the search) with ``caps=1.5`` 16.38 / 26.64 / 33.44 / 0.805, 27.61 s and 14.01 /
30.98 / 27.32 / 0.784, 17.80 s (behind on base->tip on the added four); with ``finger_dir`` 2000 too and ``caps=1.7``
16.53 / 27.01 / 32.54 / 0.803, 28.47 s and 14.16 / 30.39 / 26.39 / 0.779, 18.23 s: ahead of dex-retargeting on all
four measures on both groups, in less robot time than its hands take. That is the handshape preset now
(:meth:`LossWeights.handshape <nlo_lab.objective.LossWeights.handshape>`, :meth:`OptimizeSettings.handshape
<nlo_lab.inference.OptimizeSettings.handshape>`, ``HANDSHAPE_SLOWDOWN``); its margins on wrist->tip (0.04° on the
first group) and base->tip (0.27° on the second) are narrow, and it was chosen on all eight recordings.
Neighbours trade again: ``finger_dir`` 1500 with ``caps=1.5`` is behind on base->tip on the added four (26.83°),
``finger_dir`` 2000 with ``caps=1.5`` behind on wrist->tip on the first (16.58°), ``caps=2`` ahead on both but the
first group's robot time (29.44 s) above dex-retargeting's. On the held-out synthetic test clips (``--corpus 25``) the
new preset scores 10.56 / 15.65 / 16.41 / 0.767 (the old 10.07 / 14.82 / 18.82 / 0.783, the defaults 11.23 / 16.54 /
14.42 / 0.720), in 220.47 s of robot time against the defaults' 216.71 s.

The defaults search too (2026-11-28). On all eight recordings (``benchmarks/hands_levers.py --dex``, 08:05-08:12 UTC,
load below 1; wrist->tip / thumb / base->tip [deg] / pinch r, the clips' robot time; dex-retargeting's best 15.84 /
30.16 / 32.41 / 0.771) the preset scores 15.58 / 28.37 / 30.08 / 0.792, 46.70 s and the defaults as they were 16.20 /
26.73 / 31.19 / 0.813, 39.83 s. The preset's weights without its slowdown (``hand_slowdown`` 1) score 15.52 / 30.48 /
31.23 / 0.776, 39.72 s: at ``tip_dir`` 8000 the thumb's lead needs the slower robot. At the default ``thumb`` and
``finger_dir`` (the latent optimisation's weights unchanged) with the search and no slowdown: ``tip_dir`` 6500 15.54 /
29.66 / 31.54 / 0.786, 39.74 s; 7000 15.47 / 29.85 / 31.63 / 0.782, 39.57 s; 7500 15.44 / 30.00 / 31.72 / 0.780; the search of the ring and little fingers alone at
7000 15.68 / 29.09 / 31.71 / 0.782; 7000 without the search 15.83 / 27.88 / 32.50 / 0.781 (behind on base->tip); the
search at the old 4000 16.08 / 27.24 / 30.84 / 0.815. So the defaults are now ``tip_dir`` 7000 and the search of
``HAND_SEARCH`` (the middle, ring and little fingers; :attr:`OptimizeSettings.hand_search
<nlo_lab.inference.OptimizeSettings.hand_search>` None): ahead of dex-retargeting on all four measures, the robot no
slower than before, the latent optimisation (which runs without ``tip_dir``) and so Table I's arms unchanged. On the
held-out synthetic test clips (``--corpus 25 --dex``, 08:08-08:11 UTC) they score 10.30 / 15.65 / 17.76 / 0.771 in
212.64 s of robot time (dex-retargeting unfiltered 12.85 / 17.42 / 11.04 / 0.609, filtered 13.12 / 19.44 / 15.02 /
0.511): better than the old defaults on three measures and worse on base->tip (14.42°), as the preset is. The preset
stays for what it adds on the thumb, base->tip and the pinch at the cost of robot time (docs/RESULTS.md, "Handshapes").

It never adds a self-collision: a frame where the stage's hands would put two capsules into each
other (surface distance < 0) and the start's did not keeps the start's hands (the collision term
is a penalty the hand terms can outweigh; on Table I's YuMi test clips the stage alone put 2 more
frames into collision before this rule, measured 2026-11-26). The frames around a kept one are then
brought within the speed clamp's caps of it (:func:`within_speed` with the kept frames pinned; a frame
that this moves into a new collision is kept too): a jump into a kept frame would stretch its retimed
segment. Before this, one clip of the synthetic corpus's test split (2 kept frames of 121) stepped 0.21 rad
past a cap (``benchmarks/hands_levers.py --corpus 25``, 2026-11-27 06:33 UTC: every clip now within its
caps, the four hand measures the same to the printed digits, the 25 clips' retimed duration 216.78 ->
216.71 s; no frame is kept on ``benchmarks/hands.py``'s recordings, where nothing changes).
"""

from __future__ import annotations

import dataclasses
import time
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.human.demonstration import SIDES
from nlo_lab.inference.descent import descend, smoothness_term
from nlo_lab.inference.fast_paths import FastPaths, fast_paths
from nlo_lab.objective import LossWeights, Objective, Targets
from nlo_lab.objective.numpy_backend import HandTerms, PointTerms, SmoothTerm
from nlo_lab.objective.penetration import penetrating  # here too: where the stage's rule meets it first
from nlo_lab.robot.kinematics import KinematicTree
from nlo_lab.robot.point_gradient import MapPoints
from nlo_lab.robot.urdf import JointInfo
from nlo_lab.settings import SEARCH_GRID, SLOWDOWN_RANGE, check_range

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = ["hand_joint_mask", "refine_hands", "penetrating", "within_speed", "step_caps", "HandStageResult", "HandChains", "HandStageLoss",
           "compact_terms", "finger_joints", "path_within_caps", "searched_start", "SEARCH_GRID"]


def hand_joint_mask(robot: Robot, sides: Sequence[str] = SIDES) -> torch.Tensor:
    """``(n,)`` bool: the actuated joints that move a link below a wrist link (the fingers) of ``sides``."""
    mask = torch.zeros(robot.n_joints, dtype=torch.bool)
    for side in sides:
        wrist = robot.arm(side).wrist
        for link in robot.model.subtree(wrist):
            joint = robot.model.parent_joint(link)
            if link == wrist or joint is None or not joint.moving:
                continue
            name = joint.mimic[0] if joint.mimic else joint.name
            if name in robot.joint_names:
                mask[robot.joint_names.index(name)] = True
    return mask


_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # plan -> {(hand joints, sides): HandChains | None}


class HandChains:
    """The objective's points with the arms fixed: FK of the hand chains alone, from the wrists down.

    In the hand stage only the hand joints move, so every point on the arms, the wrist links included,
    stays where ``q0`` puts it. ``HandChains(robot, plan, index)(x, q0's points)`` maps only the points
    below a wrist, by a tree of the two hands whose root is each wrist (``T_world_point = T_world_wrist(q0)
    T_wrist_point(x)``), and puts them among ``q0``'s others: the points ``plan.map`` gives for
    ``q0`` with the hand joints ``index`` set to ``x``, without FK of the arms (YuMi: 24 of the tree's 38
    moving joints, 66 of the 174 points). FK's closed-form gradient
    (:class:`~nlo_lab.robot.point_gradient.MapPoints`) reaches ``x``. The tests hold it equal to ``plan.map``.

    Args:
        robot: the robot; plan: the objective's :class:`~nlo_lab.objective.PointPlan`;
        index: ``(h,)`` the hand joints' indices in ``q`` (:func:`hand_joint_mask` of ``sides``).
        sides: the hands whose points are mapped (the hand stage's: those with finger targets); the
            other hand's points stay ``q0``'s, as the arms'.

    Raises:
        RobotDescriptionError: a joint below a wrist is driven from above it (a mimic of an arm joint):
            :meth:`build` then returns None and the stage maps every point.
    """

    ROOT = "__wrists__"  # the hand tree's root: each wrist hangs from it at the identity

    def __init__(self, robot: Robot, plan, index: torch.Tensor, sides: Sequence[str] = SIDES):
        model = robot.model
        wrists = [robot.arm(side).wrist for side in sides]
        below = {w: set(model.subtree(w)) - {w} for w in wrists}
        hand_links = set().union(*below.values())
        joints = [JointInfo(f"{self.ROOT}{w}", "fixed", self.ROOT, w, np.eye(4), np.array([1.0, 0.0, 0.0]), 0.0, 0.0) for w in wrists]
        joints += [j for j in model.joints if j.child in hand_links]  # parents first, as in the model
        links = (self.ROOT, *wrists, *[link for link in model.links if link in hand_links])
        tree_model = dataclasses.replace(model, root=self.ROOT, links=links, joints=tuple(joints), urdf=None)
        self.tree = KinematicTree(tree_model, [robot.joint_names[i] for i in index.tolist()])
        rows = [k for k, link in enumerate(plan.links) if link in hand_links]
        side = [next(s for s, w in enumerate(wrists) if plan.links[k] in below[w]) for k in rows]
        body, vectors = self.tree.point_map([plan.links[k] for k in rows], plan.link_vectors[rows])
        device, dtype = plan.vectors.device, plan.vectors.dtype
        self.rows = torch.as_tensor(rows, dtype=torch.long, device=device)  # (k_h,) the plan's rows below a wrist
        self.side = torch.as_tensor(side, dtype=torch.long, device=device)  # (k_h,) their wrist
        self.body = torch.as_tensor(body, dtype=torch.long, device=device)
        self.vectors = torch.as_tensor(vectors, dtype=dtype, device=device)  # (k_h, 4) in the hand tree's bodies
        self.wrists = wrists

    @classmethod
    def build(cls, robot: Robot, plan, index: torch.Tensor, sides: Sequence[str] = SIDES) -> HandChains | None:
        """The hand chains, or None where a joint below a wrist does not move with the hand joints alone.

        Built once per plan (kept while it lives, as :func:`~nlo_lab.objective.point_plan` keeps the plan), hand
        joints and sides: the hand tree's constants cost about a millisecond, a tenth of a short clip's stage."""
        kept = _CHAINS.setdefault(plan, {}) if getattr(plan, "robot", None) is robot else {}  # the plan's own robot
        key = (tuple(index.tolist()), tuple(sides))
        if key not in kept:
            try:
                kept[key] = cls(robot, plan, index, sides)
            except RobotDescriptionError:
                kept[key] = None
        return kept[key]

    def __call__(self, x: torch.Tensor, points: torch.Tensor, wrists: torch.Tensor) -> torch.Tensor:
        """``x (T, h)`` the hand joints -> ``(T, k, 3)``: ``points`` (``q0``'s) with the rows below a wrist mapped for ``x``.

        ``wrists``: ``(T, 2, 3, 4)`` the wrist links' world poses ``[R | t]`` at ``q0``."""
        local = self.tree.map_points(x, self.body, self.vectors, analytic_gradient=True)  # (T, k_h, 3) in the wrist frames
        pose = wrists[:, self.side]  # (T, k_h, 3, 4)
        world = (pose[..., :3] @ local[..., None])[..., 0] + pose[..., 3]
        return points.index_copy(1, self.rows, world)


def compact_terms(terms: PointTerms, moving: np.ndarray, points: np.ndarray) -> tuple[PointTerms, np.ndarray, np.ndarray, np.ndarray]:
    """``terms`` on the points the hand stage needs: the moving ones and the fixed ones a term combines with them.

    In the hand stage most of the objective's points do not move (the arms, the body, a hand never seen), and
    most of its residual rows (ee, ori, elbow) combine only such points. This form keeps the rows and the
    capsule pairs that reach a moving point, over the points they use: a residual row
    without a moving point adds a constant per frame to its term and nothing to the gradient of a moving
    point (as :meth:`PointTerms.held <nlo_lab.objective.numpy_backend.PointTerms.held>` does for the pairs).

    Args:
        terms: the held numpy terms (``PointTerms.held``, the pairs without a moving end measured once).
        moving: ``(m,)`` the rows of the plan's points that move (the hand chains' rows, in their order).
        points: ``(T, K, 3)`` the start's points (the fixed rows' values).

    Returns:
        ``(compact, keep, at)``, ``constant (T, 4)``: the terms over the points ``points[:, keep]`` (the fixed ones in
        the plan's order, then ``moving``), ``at (m,)`` the moving points' places among them (the last m), and the
        held rows' share of the row terms (ee, ori, elbow, finger) per frame.
    """
    moving = np.asarray(moving, dtype=np.int64)
    K = points.shape[1]
    is_moving = np.zeros(K, dtype=bool)
    is_moving[moving] = True
    live = np.any(terms.rows[:, is_moving] != 0, axis=1)  # (V,) the residual rows that combine a moving point
    hand = terms.hand
    pairs = terms.pair_points.reshape(-1, 4)
    capsules = np.unique(terms.pair_capsules)  # the capsules of the pairs measured each step
    used = np.zeros(K, dtype=bool)
    used[np.flatnonzero(np.any(terms.rows[live] != 0, axis=0))] = True
    for rows in (hand.plus, hand.minus, hand.axes, pairs.reshape(-1), terms.capsule_rows.reshape(-1, 2)[capsules].reshape(-1)):
        used[rows] = True
    # the fixed points in the plan's order, then the moving ones in the hand chains' (one block: the stage writes them
    # and reads their gradient as a slice, no gather or scatter); every sum the same (a live row has two points)
    keep = np.concatenate([np.flatnonzero(used & ~is_moving), moving])
    at = np.full(K, -1, dtype=np.int64)
    at[keep] = np.arange(len(keep))
    finger_row = np.zeros(len(terms.rows), dtype=bool)
    finger_row[terms.fingers] = True
    row_term = terms.term_of_row.argmax(1)
    kind = hand.kind.argmax(1)
    compact_hand = HandTerms(at[hand.plus], at[hand.minus], at[hand.axes], hand.side, hand.length[:, 0], kind, hand.v_hat,
                             hand.mask[..., 0], hand.pinch_goal, hand.pinch_weight, hand.gap_below)
    capsule_of = np.full(len(terms.capsule_rows) // 2, -1, dtype=np.int64)
    capsule_of[capsules] = np.arange(len(capsules))
    out = PointTerms(terms.rows[live][:, keep], finger_row[live], row_term[live], terms.goal[:, live], terms.mask[:, live, 0],
                     at[pairs].reshape(-1), terms.radii, terms.margins, terms.form, compact_hand,
                     at[terms.capsule_rows.reshape(-1, 2)[capsules]].reshape(-1), capsule_of[terms.pair_capsules])
    out.collision_held = terms.collision_held
    # the held rows' share: the whole terms' row terms at the start less the live rows' (their points do not move; no pair measured)
    whole = terms.forward(points, pairs=False)[0][:, :4].astype(np.float64)
    live_part = out.forward(np.ascontiguousarray(points[:, keep]), pairs=False)[0][:, :4].astype(np.float64)
    return out, keep, at[moving], whole - live_part


class HandStageLoss:
    """The hand stage's loss ``(T,)`` and its gradient in the hand joints ``x (T, h)``, chained by hand: the fast
    form of :func:`refine_hands`' evaluation (``FastPaths.written_gradient``), the same numbers without an
    autograd graph per step (the tests hold the two equal, values and gradients).

    Forward: the hand chains' points in the wrist frames (:meth:`MapPoints.points
    <nlo_lab.robot.point_gradient.MapPoints.points>`), ``p = R_wrist p_local + t_wrist`` into the start's
    points, the held numpy terms (:meth:`~nlo_lab.objective.numpy_backend.PointTerms.held`) weighted, and the
    smoothness term of the whole angles (:class:`~nlo_lab.objective.numpy_backend.SmoothTerm`). Backward: the
    terms' gradient onto the points, ``g_local = R_wristᵀ g_p`` on the hands' rows, FK's closed form
    (:meth:`MapPoints.gradient <nlo_lab.robot.point_gradient.MapPoints.gradient>`), plus the smoothness
    term's gradient in the hand joints' columns.

    Args:
        chains: the :class:`HandChains`; terms: the held numpy terms; weights: ``(len(TERMS),)`` the objective's;
        points: ``(T, K, 3)`` the start's points; wrists: ``(T, 2, 3, 4)`` the wrists' poses at the start;
        start: ``(T, n)`` the start's angles; index: ``(h,)`` the hand joints; smooth: the smoothness term or None.
    """

    def __init__(self, chains: HandChains, terms: PointTerms, weights: torch.Tensor, points: torch.Tensor, wrists: torch.Tensor,
                 start: torch.Tensor, index: torch.Tensor, smooth: SmoothTerm | None):
        self.chains, self.smooth, self.start, self.index = chains, smooth, start, index
        self.weights = weights.detach().cpu().numpy()
        self.rows, self.columns = chains.rows.cpu().numpy(), index.cpu().numpy()
        # the terms over the points they need, the moving ones first; the held rows' share a constant per frame
        self.terms, keep, moving, constant = compact_terms(terms, self.rows, points.detach().cpu().numpy())
        self.moving = slice(int(moving[0]), int(moving[-1]) + 1)  # the last block of the points (compact_terms)
        self.fixed = np.ascontiguousarray(points.detach().cpu().numpy()[:, keep])  # (T, K_c, 3): the start's
        self.constant = constant.astype(self.fixed.dtype)  # (T, 4)
        pose = wrists[:, chains.side].detach().cpu().numpy()  # (T, k_h, 3, 4) each row's wrist [R | t]
        # R's columns and rows, contiguous: R p and Rᵀ g written out over the 3 (torch's stacked 3x3 products cost 3x)
        self.R_columns = [np.ascontiguousarray(pose[..., :, j]) for j in range(3)]
        self.R_rows = [np.ascontiguousarray(pose[..., i, :3]) for i in range(3)]
        self.t = np.ascontiguousarray(pose[..., 3])
        self.g_terms = np.tile(self.weights, (len(start), 1))  # the backward of sum(loss): each term's gradient is its weight

    def value(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``loss (T,)``, the angles ``(T, n)`` and the unweighted terms ``(T, len(TERMS))``, without the gradient."""
        return self._forward(x)[:3]

    def __call__(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``loss (T,)``, the angles ``(T, n)``, the unweighted terms ``(T, len(TERMS))`` and ``dL/dx (T, h)``."""
        loss, full, terms, (poses, local, state, smooth_state) = self._forward(x)
        c = self.chains
        g_points = self.terms.backward(self.g_terms.astype(self.fixed.dtype, copy=False), state)
        g, (r0, r1, r2) = g_points[:, self.moving], self.R_rows
        g_local = torch.from_numpy(r0 * g[..., 0:1] + r1 * g[..., 1:2] + r2 * g[..., 2:3])  # Rᵀ g
        g_x = MapPoints.gradient(g_local, poses, local, c.tree, c.body, c.vectors)
        if self.smooth is not None:
            g_x = g_x + torch.from_numpy(self.smooth.backward(np.ones(len(x), dtype=self.fixed.dtype), smooth_state)[:, self.columns])
        return loss, full, terms, g_x

    def _forward(self, x: torch.Tensor):
        c, x = self.chains, x.detach()
        poses, local = MapPoints.points(x, c.tree, c.body, c.vectors)  # (T, k_h, 3) in the wrist frames
        p, (c0, c1, c2) = local.numpy(), self.R_columns
        P = self.fixed.copy()
        P[:, self.moving] = c0 * p[..., 0:1] + c1 * p[..., 1:2] + c2 * p[..., 2:3] + self.t  # R p + t, as HandChains.__call__
        terms, state = self.terms.forward(P)
        terms[:, :4] += self.constant
        loss = terms @ self.weights
        full = self.start.index_copy(1, self.index, x)
        smooth_state = None
        if self.smooth is not None:
            smooth, smooth_state = self.smooth.forward(full.numpy())
            loss = loss + smooth
        return (torch.from_numpy(np.ascontiguousarray(loss)), full, torch.from_numpy(terms),
                (poses, local, state, smooth_state))


@dataclass
class HandStageResult:
    """What :func:`refine_hands` found.

    Attributes:
        q: ``(T, n)`` the angles, hand joints optimised, the others as given.
        loss: ``(T,)`` the objective per frame at ``q`` (without the latent term; the smoothness
            term's share of each frame included when it applies).
        terms: ``(T, len(TERMS))`` unweighted terms at ``q``.
        history: mean loss per evaluation; steps: Adam steps taken; seconds: wall time.
        kept: ``(T,)`` bool, the frames that kept the start's hands (the stage's would collide, the start's not).
    """

    q: torch.Tensor
    loss: torch.Tensor
    terms: torch.Tensor
    history: list[float]
    steps: int
    seconds: float
    kept: torch.Tensor


def refine_hands(robot: Robot, q: torch.Tensor, targets: Targets, weights: LossWeights | None = None, *,
                 iterations: int = 30, patience: int = 5, lr: float = 0.05, collision_form: str = "hinge",
                 anchor: torch.Tensor | None = None, fast: bool | FastPaths = False, search: Sequence[str] = (),
                 grid: int = SEARCH_GRID, slowdown: float = 1.0) -> HandStageResult:
    """Optimise the hand joints of ``q (T, n)`` on the objective of ``targets``, the other joints kept.

    Only the hands with a finger target in some frame of ``targets`` move; a hand never seen keeps ``q``'s joints.

    Args:
        robot: the robot; without hand joints (or no hand seen) ``q`` comes back unchanged (0 steps).
        q: ``(T, n)`` start angles [rad] (the latent optimisation's).
        targets: :class:`~nlo_lab.objective.Targets` of the T frames.
        weights: the objective's weights (:class:`~nlo_lab.objective.LossWeights`), as the latent optimisation's.
        iterations, patience, lr: Adam's steps, the stop after ``patience`` evaluations without
            improvement, its step [rad].
        collision_form: as :class:`~nlo_lab.inference.OptimizeSettings`.
        anchor: ``(n,)`` the frame before ``targets`` (a previous chunk's last): frame 0 pays its step from it.
        fast: the objective's evaluation (:func:`~nlo_lab.inference.fast_paths`); same numbers either way.
        search: fingers (names of ``FINGERS``) whose own joints (:func:`finger_joints`) are first searched along the
            whole clip, one joint at a time, each hand the clip shows (:func:`searched_start`: ``grid`` values, the
            speed clamp's caps between frames, the objective without the smoothness term); Adam starts there.
        slowdown: the speed clamp's caps (:func:`step_caps`) times this (``OptimizeSettings.hand_slowdown``): each
            retimed segment at most ``slowdown`` times the start's (1: the robot never slower than the start).
    """
    start = time.perf_counter()
    slowdown = check_range("slowdown", slowdown, *SLOWDOWN_RANGE)
    weights = weights or LossWeights()
    dtype = robot.lower_limits.dtype
    targets = targets.to(dtype=dtype)
    q0 = q.detach().to(dtype)
    # only the hands with a finger target in some frame: an unseen hand keeps the start's joints (nothing to follow)
    seen = [side for k, side in enumerate(SIDES) if bool(targets.finger_mask[:, k].any())]
    hand = hand_joint_mask(robot, seen).to(q0.device)
    index = hand.nonzero().flatten()
    paths = fast_paths(fast, len(targets), targets.shoulder.device)
    loss_fn = Objective(robot, targets, weights, collision_form, **paths.objective_options())
    smooth = smoothness_term(robot, targets, weights, anchor)
    lo, hi = robot.lower_limits[index], robot.upper_limits[index]

    def angles(x: torch.Tensor) -> torch.Tensor:
        return q0.index_copy(1, index, x)  # the hand joints from x, the others as given

    chains = HandChains.build(robot, loss_fn.plan, index, seen) if paths.hand_chains and index.numel() else None
    fixed_points = held = None  # q0's points, mapped once (the hand chains' arms; the start's collision verdicts)
    if chains is not None:  # the arms' points and the wrists' poses, fixed for the whole stage
        with torch.no_grad():
            fixed_points = loss_fn.plan.map(q0)
            wrist_poses = robot.forward_kinematics_links(q0, chains.wrists)[..., :3, :]
        if loss_fn.numpy_terms is not None:  # with the numpy terms: the capsule pairs of the arms alone measured once
            moving = np.zeros(fixed_points.shape[1], dtype=bool)
            moving[chains.rows.cpu().numpy()] = True
            held = loss_fn.numpy_terms.held(moving, fixed_points.cpu().numpy())

    written = None  # the descent's loss and gradient chained by hand (FastPaths.written_gradient), where it applies
    if (chains is not None and held is not None and fixed_points is not None and paths.written_gradient
            and len(loss_fn.weights) == held.n_terms):
        numpy_smooth = None  # the smoothness term where it applies (smoothness_term's rule), in numpy
        if smooth is not None and targets.fps is not None:
            numpy_smooth = SmoothTerm(float(targets.fps), robot.velocity_limits, weights.smooth, anchor, dtype)
        written = HandStageLoss(chains, held, loss_fn.weights, fixed_points, wrist_poses, q0, index, numpy_smooth)

    def evaluate(x):
        full = angles(x)
        if chains is None:
            total, terms = loss_fn(full)
        else:  # the same objective, FK of the hands alone
            total, terms = loss_fn.of_points(chains(x, fixed_points, wrist_poses), held)
        if smooth is not None:
            total = total + smooth(full)
        return total, full, terms

    def project(x):  # inside the limits
        x.copy_(torch.maximum(torch.minimum(x, hi), lo))

    if index.numel() == 0 or len(targets) == 0:
        iterations = 0
    x0 = q0[:, index].clamp(lo, hi)  # the start's hands: where a frame that would collide goes back to
    x_start = x0
    if search and iterations:
        caps0 = None  # frame by frame without a frame rate (as the speed clamp below)
        if targets.fps is not None and len(targets) > 1:
            caps0 = slowdown * step_caps(q0, robot.velocity_limits, float(targets.fps))[:, index]
        columns = [int((index == j).nonzero()) for side in seen for finger in search for j in finger_joints(robot, side, finger)]
        weights_t = loss_fn.weights

        def frame_cost(x):  # the objective per frame, without the smoothness term (the caps bound the steps)
            return (written.value(x)[2] if written is not None else evaluate(x)[2]) @ weights_t.to(x.dtype)

        with torch.no_grad():
            x_start = searched_start(x0, frame_cost, columns, lo, hi, caps0, grid)
    step: Callable[[torch.Tensor], Any] = evaluate if written is None else written
    final = evaluate if written is None else written.value  # the result's loss and terms: no gradient
    _, best_q, loss, terms, history, steps = descend(x_start, step, project, iterations, patience, lr, None, per_sample=smooth is None)
    best_q = best_q.detach()
    with torch.no_grad():
        caps = None
        if targets.fps is not None and len(targets) > 1:  # never slower than the start (times slowdown)
            caps = slowdown * step_caps(q0, robot.velocity_limits, float(targets.fps))[:, index]
            x = within_speed(best_q[:, index], caps)
            best_q = angles(x)
            loss, _, terms = final(x)
        # never a new self-collision: such a frame keeps the start's hands (the start's verdicts only when needed)
        cull = paths.cull_far_pairs
        kept = penetrating(robot, best_q, cull)
        if bool(kept.any()):
            start_penetrates = penetrating(robot, q0, cull, points=fixed_points)
            kept &= ~start_penetrates
            while bool(kept.any()):
                # the kept frames pinned to the start's hands, their neighbours brought within the caps of them (a
                # jump into a kept frame would stretch its retimed segment); that may touch a frame the clamp moved
                # into a new collision: it is kept too, until none is (the start's hands satisfy every rule)
                x = torch.where(kept[:, None], x0, best_q[:, index])
                if caps is not None:
                    x = within_speed(x, caps, pinned=kept)
                best_q = angles(x)
                added = penetrating(robot, best_q, cull) & ~start_penetrates & ~kept
                if not bool(added.any()):
                    break
                kept |= added
            loss, _, terms = final(best_q[:, index])
    return HandStageResult(best_q, loss.detach(), terms.detach(), history, steps, time.perf_counter() - start, kept)


def finger_joints(robot: Robot, side: str, finger: str) -> list[int]:
    """Indices into ``robot.joint_names`` of the actuated joints that move ``finger``'s tip link of ``side`` and no
    other finger's: what a search of that finger sets (:meth:`Robot.finger_joints
    <nlo_lab.robot.Robot.finger_joints>`, which ``nlo-lab robot check`` reports too)."""
    return robot.finger_joints(side, finger)


def path_within_caps(cost: np.ndarray, values: np.ndarray, caps: np.ndarray | None) -> tuple[np.ndarray, float]:
    """The path of least cost through a table: ``(T,)`` indices ``i_t`` into ``values (G,)`` minimising
    ``sum_t cost[i_t, t]`` (``cost (G, T)``) with every step ``|values[i_t] - values[i_(t-1)]| <= caps[t-1]``
    (``caps (T-1,)``; None: no bound, each frame its own best), and that sum. Dynamic programming (Viterbi):
    ``G² T`` comparisons."""
    G, T = cost.shape
    if caps is None:
        best = cost.argmin(0)
        return best, float(cost[best, np.arange(T)].sum())
    jump = np.abs(values[:, None] - values[None, :])  # [to, from]
    total, back = cost[:, 0].astype(np.float64), np.zeros((T, G), dtype=np.int64)
    for t in range(1, T):
        reach = np.where(jump <= caps[t - 1] + 1e-9, total[None, :], np.inf)  # 1e-9: a cap equal to a grid step
        back[t] = reach.argmin(1)
        total = reach.min(1) + cost[:, t]
    path = np.zeros(T, dtype=np.int64)
    path[-1] = int(total.argmin())
    for t in range(T - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path, float(total[path[-1]])


def searched_start(x: torch.Tensor, frame_cost: Callable[[torch.Tensor], torch.Tensor], columns: Sequence[int],
                   lo: torch.Tensor, hi: torch.Tensor, caps: torch.Tensor | None, grid: int = SEARCH_GRID) -> torch.Tensor:
    """``x (T, h)`` with each of ``columns`` in turn set along the whole clip to the path of least objective over
    ``grid`` values spread evenly over its limits ``lo``, ``hi`` (``(h,)``), every step within ``caps (T-1, h)``
    (:func:`path_within_caps`; None: frame by frame), the other columns as they are. ``frame_cost(x) -> (T,)`` is
    the objective per frame. A column keeps its values where the path would cost more than they do (they are
    within the caps: the caps are at least the start's steps)."""
    x = x.clone()
    for c in columns:
        values = torch.linspace(float(lo[c]), float(hi[c]), grid, dtype=x.dtype)
        table = []
        for v in values:
            trial = x.clone()
            trial[:, c] = v
            table.append(frame_cost(trial))
        cost = torch.stack(table).double().numpy()
        path, total = path_within_caps(cost, values.double().numpy(), None if caps is None else caps[:, c].double().numpy())
        if total < float(frame_cost(x).double().sum()):
            x[:, c] = values[torch.as_tensor(path)]
    return x


def step_caps(start: torch.Tensor, velocity_limits: torch.Tensor, fps: float) -> torch.Tensor:
    """``(T-1, n)`` the largest step [rad] of each joint between consecutive frames of ``start (T, n)`` that
    leaves the retimed segment no longer than the start's: ``v_j dt_i``, ``dt_i = max(1/fps, max_k |Δq_k,i|/v_k)``
    (:func:`~nlo_lab.inference.retime.segment_durations`' time of the start's segment; unlimited joints count 0)."""
    ratio = torch.where(torch.isfinite(velocity_limits), (start[1:] - start[:-1]).abs() / velocity_limits, 0.0)
    dt = ratio.amax(1, keepdim=True).clamp_min(1.0 / fps) if ratio.shape[1] else ratio.new_full((ratio.shape[0], 1), 1.0 / fps)
    return velocity_limits * dt


def within_speed(x: torch.Tensor, cap: torch.Tensor, pinned: torch.Tensor | None = None) -> torch.Tensor:
    """``x (T, h)`` with each joint's step between consecutive frames at most ``cap (T-1, h)`` [rad]
    (:func:`step_caps`), clamped frame by frame from frame 0.

    ``pinned``: ``(T,)`` bool, frames that keep their ``x``; they must lie within the caps of one another (the
    start's frames do: the caps are at least the start's steps). Every frame is first brought within reach of the
    nearest pinned frame on each side (the caps summed between them), so the clamp from frame 0 never has to move a
    pinned frame: clamping a frame that is within reach into the step from its clamped predecessor keeps it within
    reach (the two ranges overlap), and a pinned frame's range is its own value."""
    bound = cap.detach().cpu().numpy()
    start = x.detach().cpu().numpy()
    out = start.copy()  # frame by frame in numpy: a torch op per frame cost 10x as much
    keep = np.zeros(len(out), dtype=bool) if pinned is None else pinned.detach().cpu().numpy()
    if keep.any():
        pins = np.flatnonzero(keep)
        # frame 0 -> t, summed in float64: a long clip's sums in float32 would be off by more than a step's last bit
        reach = np.concatenate([np.zeros((1, out.shape[1])), np.cumsum(bound, 0, dtype=np.float64)])
        lo, hi = np.full(out.shape, -np.inf), np.full(out.shape, np.inf)
        for k, first, last in zip(pins, np.r_[0, pins[:-1]], np.r_[pins[1:], out.shape[0] - 1], strict=True):
            for side in (slice(first, k + 1), slice(k, last + 1)):  # the frames whose nearest pinned frame k is
                span = np.abs(reach[side] - reach[k])
                lo[side], hi[side] = np.maximum(lo[side], out[k] - span), np.minimum(hi[side], out[k] + span)
        np.clip(out, lo, hi, out=out)
    for t in range(1, out.shape[0]):
        np.clip(out[t], out[t - 1] - bound[t - 1], out[t - 1] + bound[t - 1], out=out[t])
    out[keep] = start[keep]  # exactly: the sums of the caps and the steps may differ in their last bit
    return torch.as_tensor(out, device=x.device)
