"""``pasta pipeline [key=value ...]``: demonstrations, then every learned module, resumably."""

from __future__ import annotations

import argparse
import sys

HELP = ("generate the demonstrations and train every learned module in one resumable run "
        "(demos -> vae -> feasibility -> cost -> policy -> reset -> select; done units are skipped, "
        "interrupted ones resume)")

EPILOG = """arguments (key=value):
  data=data/demos        dataset directory (written by demos, read by the training stages)
  out=models             models root; OUT/pipeline.json records the settings of every unit
  num_demos=200          demonstrations per skill (same as demos.num)
  variant_demos=-1       demonstrations per scene variant a skill asks the pipeline for, added after
                         its default ones (push: 150 scene=wide, unit demos/push-wide); -1: each
                         variant's own number; 0: none
  workers=2              demo generation processes (same as demos.workers); with backend=ray the
                         most demos in flight (0: as many as the cluster has CPUs)
  backend=local          local | ray: where the demos units make their demonstrations (Ray tasks;
                         ray.address=auto joins a cluster, none starts a local Ray instance;
                         `pip install pasta-dough[ray]`, docs/scaling.md); never causes a rerun
  deadline_s=0           seconds a worker may spend on one demonstration before it is killed (Ray:
                         its task cancelled) and the demo retried once, then reported; 0: derived
                         from each skill's max_steps and n_particles (11-13 min at the defaults);
                         never causes a rerun
  stages=demos,vae,feasibility,cost,policy,reset,select
                         stages to run, in this order whatever the order given
  skills=auto            skills of the per-skill stages (demos, feasibility, policy, reset, select);
                         auto: every registered skill whose plugin can make demonstrations
                         (built-ins: cut, push, roll)
  reset_skills=auto      policies that get a learned reset (start) pose (stage reset); auto: the
                         skills whose plugin asks for it (built-ins: cut); empty: none
  select_skills=auto     policies whose stopping rule is chosen on validation configs (stage select);
                         auto: the skills whose plugin asks for it (built-ins: cut, roll, lift); empty: none
  only=UNIT[,UNIT]       run these units only: a unit (feasibility/cut) or a whole stage (cost)
  force=true             rerun the selected units even when done (demonstrations are never deleted)
  progress=false         hide the inner progress bars (drawn on stderr when it is a terminal)
  threads=0              CPU threads of every unit: torch's in the training units, the simulator's in
                         the demos units; 0: the stages' own (1 for training, the simulator's default
                         for demos); <stage>.threads= still wins; never causes a rerun
  <stage>.<key>=value    a setting of every unit of a stage, e.g. vae.epochs=5, policy.batch_size=16
  <stage>.<skill>.<key>=value
                         a setting of one skill's unit, e.g. feasibility.push.epochs=30
  The keys are those of `pasta demos` and `pasta train <stage>` (docs/learning.md; reset and
  select: docs/policies.md); a typo is reported with the closest valid key before anything runs.

units and defaults (sized for a 2-core CPU; the settings the shipped models were trained with; the
per-skill ones come from each skill plugin's training_defaults and demo_variants):
  demos/<skill>          pasta demos skill=<skill> num=<num_demos> workers=<workers> out=<data>
  demos/push-wide        pasta demos skill=push num=<num_demos + 150> scene=wide ...
  demos/push-nudge       pasta demos skill=push num=<num_demos + 300> scene=nudge ... (read by policy/push only)
  demos/cut-long         pasta demos skill=cut num=<num_demos + 150> scene=long ... (read by reset/cut only)
  demos/roll-board       pasta demos skill=roll num=<num_demos + 100> scene=board ...
  demos/roll-sheet       pasta demos skill=roll num=<num_demos + 250> scene=sheet ... (read by policy/roll only)
  vae                    epochs=11 stride=5 threads=1                       -> OUT/vae
  feasibility/<skill>    threads=1; cut stride=3 (epochs 30) shift_per_positive=5 shift_entities=one
                         shift_max=0.25; push and roll stride=4 epochs=20   -> OUT/feasibility/<skill>
  cost                   stride=5 threads=1 (epochs 60)                     -> OUT/cost
  policy/<skill>         epochs=40 steps_per_epoch=50 threads=1             -> OUT/policy/<skill>
                         (step_feature and pose_feature on: the defaults); cut: start_at_reset=true;
                         push and lift: goal_feature=true; lift: decoded_goals=0.5 decoded_noise=0.5
                         decoded_shift=0.03; roll: action_feature=true floor_y=true
  reset/cut              pasta train reset threads=1 (epochs 90, start_step 0, points 1000) target=skill
                         piece_share=true x_share=true decoded_goals=0.5 decoded_noise=0.5
                                                                -> OUT/policy/cut/reset.* (+ reset_metrics.json)
  select/<skill>         pasta train select n=20 seed=2000 write=true threads=1 (validation
                         configs; the rule goes into OUT/policy/<skill>/model.json, the per-config
                         results into select.json); cut thresholds=0.3,...,0.7
                         max_steps=0,40,45,50,55,60,65,70,80,100; roll thresholds=0.3,...,0.8
                         min_steps=1,20 max_steps=0,60
  vae and cost train on every skill found in data; feasibility and cost use OUT/vae; reset and select
  run after every policy unit (a cut rule is chosen with the cut's reset pose in place).

resuming:
  A unit is done when its metrics.json (reset: reset_metrics.json, select: select.json and the rule
  still in model.json) exists and OUT/pipeline.json says it was produced with the same settings
  (trainer config, dataset path and demo counts, for feasibility and cost the VAE weights, for select
  the policy and reset weights): it is skipped. A unit stopped half-way resumes from its last.*
  checkpoint (reset: reset_last.*; select: at the first config it had not scored). A unit
  with other settings (or no record) starts afresh; a retrained VAE reruns feasibility and cost, a
  retrained policy its select unit, more demonstrations rerun the units that read them. progress,
  threads, resume and workers never cause a rerun. Each unit prints a line when it starts and one
  when it ends (wall time and its held-out figure); a table sums up at the end.

examples:
  pasta pipeline                                         # everything, defaults (hours on 2 cores)
  pasta pipeline num_demos=50 out=models_small           # a smaller dataset, another models root
  pasta pipeline stages=vae,feasibility,cost             # retrain from existing demonstrations
  pasta pipeline only=feasibility/cut feasibility.epochs=40   # one unit, with more epochs
  pasta pipeline stages=policy skills=cut,roll policy.epochs=20
  pasta pipeline stages=select select.n=10              # re-choose the stopping rules (cut, roll)
  pasta pipeline force=true only=cost                    # retrain the cost model even if done
  pasta pipeline backend=ray ray.address=auto workers=0  # demonstrations on the Ray cluster
  make train                                             # the same as `pasta pipeline`"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="pipeline arguments and <stage>.<key>=value settings (see below)")


def run(args: argparse.Namespace) -> int:
    from pasta.pipeline import run_pipeline

    try:
        results = run_pipeline(args.overrides)
    except KeyboardInterrupt:
        print("pasta pipeline: interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    return 0 if all(r.status in ("ran", "skipped") for r in results) else 1
