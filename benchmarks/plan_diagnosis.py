"""Plan a task instance as `pasta run` does and print what the planner saw (issue 22 diagnosis).

    python benchmarks/plan_diagnosis.py crs_distractors 1004,1006,1000 [planner.KEY=VALUE ...]

Per seed: the observed and goal entity centroids, their Chamfer distances and learned costs (obs x
goal), the default plan (skills, attention, feasibility, set cost, score, the best sequences) and the
plan with the skeleton cut,push,roll given. The problems are built without `fixed`, i.e. as the planner
planned before issue 22 (without fixed entities the draws are the same): the numbers of docs/planning.md,
"Pieces already at their goal piece".
"""
import sys, json, time
import numpy as np, torch
torch.set_num_threads(1)
from pasta.execute.session import build_session
from pasta.execute.pipeline import perceive
from pasta.core.planner import PlanningProblem
from pasta.core.metrics import chamfer
task = sys.argv[1]; seeds = [int(s) for s in sys.argv[2].split(",")]
extra = sys.argv[3:]
s = build_session(task, config_overrides=extra)
for seed in seeds:
    t0 = time.time()
    inst = s.task.instance(seed)
    tg = time.time() - t0
    sim = s.task.make_sim(); sim.set_state(inst.init)
    obs = sim.observe().dough
    eo, uo = perceive(obs, s.encoder, seed=seed)
    eg, ug = perceive(inst.goal, s.encoder, seed=seed)
    d = chamfer(torch.as_tensor(np.stack(eo))[:, None], torch.as_tensor(np.stack(eg))[None]).numpy()
    cents_o = [e.mean(0).round(3).tolist() for e in eo]; cents_g = [e.mean(0).round(3).tolist() for e in eg]
    print(f"seed {seed} (instance {tg:.1f}s) obs centroids {cents_o}\n goal centroids {cents_g}\n chamfer obs x goal:\n{np.array2string(d, precision=5)}")
    with torch.no_grad():
        c = s.cost.pairwise(uo[:, None].expand(-1, len(ug), -1).reshape(-1, 1, uo.shape[1]), ug[None].expand(len(uo), -1, -1).reshape(-1, 1, ug.shape[1])).reshape(len(uo), len(ug))
    print(" learned cost obs x goal:\n", np.array2string(c.numpy(), precision=5))
    for skel in (None, ("cut", "push", "roll")):
        p = PlanningProblem(obs=uo, goal=ug, skills=s.skills, encoder=s.encoder, cost=s.cost, horizon=3, seed=seed, skeleton=skel)
        t1 = time.time(); plan = s.planner.plan(p); tp = time.time() - t1
        ps = sorted(plan.info["per_sequence"], key=lambda r: -r["score"])[:4]
        print(f" skeleton={skel}: {plan.skills} inputs {[st.inputs for st in plan.steps]} feas {[round(st.feasibility,3) for st in plan.steps]} cost {plan.final_cost:.5f} score {plan.score:.3f} clearance {plan.info.get('clearance_penalty')} ({tp:.1f}s)")
        if skel is None:
            print("  top sequences:", [(r["skills"], round(r["score"], 3)) for r in ps])
    sys.stdout.flush()
