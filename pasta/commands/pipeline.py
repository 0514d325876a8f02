"""``pasta pipeline [key=value ...]``: demonstrations, then every learned module, resumably."""

from __future__ import annotations

import argparse
import sys

HELP = ("generate the demonstrations and train every learned module in one resumable run "
        "(demos -> vae -> feasibility -> cost -> policy; done units are skipped, interrupted ones resume)")

EPILOG = """arguments (key=value):
  data=data/demos        dataset directory (written by demos, read by the training stages)
  out=models             models root; OUT/pipeline.json records the settings of every unit
  num_demos=200          demonstrations per skill (same as demos.num)
  wide_push_demos=150    long push demonstrations added after the push ones (demos/push-wide; 0: none)
  workers=2              demo generation processes (same as demos.workers)
  stages=demos,vae,feasibility,cost,policy
                         stages to run, in this order whatever the order given
  skills=cut,push,roll   skills of the per-skill stages (demos, feasibility, policy)
  only=UNIT[,UNIT]       run these units only: a unit (feasibility/cut) or a whole stage (cost)
  force=true             rerun the selected units even when done (demonstrations are never deleted)
  progress=false         hide the inner progress bars
  <stage>.<key>=value    a setting of every unit of a stage, e.g. vae.epochs=5, policy.batch_size=16
  <stage>.<skill>.<key>=value
                         a setting of one skill's unit, e.g. feasibility.push.epochs=30
  The keys are those of `pasta demos` and `pasta train <stage>` (see docs/learning.md); a typo is
  reported with the closest valid key before anything runs.

units and defaults (sized for a 2-core CPU; the settings the shipped models were trained with):
  demos/<skill>          pasta demos skill=<skill> num=<num_demos> workers=<workers> out=<data>
  demos/push-wide        pasta demos skill=push num=<num_demos + wide_push_demos> scene=wide ...
  vae                    epochs=11 stride=5 threads=1                       -> OUT/vae
  feasibility/<skill>    threads=1; cut stride=3 (epochs 30);
                         push and roll stride=4 epochs=20                   -> OUT/feasibility/<skill>
  cost                   stride=5 threads=1 (epochs 60)                     -> OUT/cost
  policy/<skill>         epochs=40 steps_per_epoch=50 threads=1             -> OUT/policy/<skill>
  vae and cost train on every skill found in data; feasibility and cost use OUT/vae.

resuming:
  A unit is done when its metrics.json exists and OUT/pipeline.json says it was produced with the
  same settings (trainer config, dataset path and demo counts, and for feasibility and cost the VAE
  weights): it is skipped. A unit stopped half-way resumes from its last.* checkpoint. A unit with
  other settings (or no record) starts afresh; a retrained VAE reruns feasibility and cost, more
  demonstrations rerun the units that read them. progress, threads, resume and workers never
  cause a rerun. Each unit prints a line when it starts and one when it ends (wall time and its
  held-out figure); a table sums up at the end.

examples:
  pasta pipeline                                         # everything, defaults (hours on 2 cores)
  pasta pipeline num_demos=50 out=models_small           # a smaller dataset, another models root
  pasta pipeline stages=vae,feasibility,cost             # retrain from existing demonstrations
  pasta pipeline only=feasibility/cut feasibility.epochs=40   # one unit, with more epochs
  pasta pipeline stages=policy skills=cut,roll policy.epochs=20
  pasta pipeline force=true only=cost                    # retrain the cost model even if done
  make train                                             # the same as `pasta pipeline`"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("overrides", nargs="*", metavar="key=value",
                        help="pipeline arguments and <stage>.<key>=value settings (see below)")


def run(args: argparse.Namespace) -> int:
    from pasta.train.pipeline import run_pipeline

    try:
        results = run_pipeline(args.overrides)
    except KeyboardInterrupt:
        print("pasta pipeline: interrupted; run the same command again to resume", file=sys.stderr)
        return 130
    return 0 if all(r.status in ("ran", "skipped") for r in results) else 1
