"""Per-skill point-cloud policies (torch): PointNet++ over dough + tool + sub-goal points.

- :mod:`pasta.policy.pointnet2`: farthest point sampling, ball query, set abstraction, PointNet++;
- :mod:`pasta.policy.network`: :class:`~pasta.policy.network.PolicyNet` (action in [-1, 1] + done logit);
- :mod:`pasta.policy.dataset`: behaviour-cloning batches with hindsight goals from demonstrations;
- :mod:`pasta.policy.train`: :func:`~pasta.policy.train.train_policy` through the shared loop;
- :mod:`pasta.policy.learned`: :class:`~pasta.policy.learned.LearnedPolicy`, attached to a skill with
  ``skill.attach_policy``; its ``controller(skill)`` drives the skill in the simulator;
- :mod:`pasta.policy.evaluate`: single-skill evaluation of learned / heuristic / expert controllers.

Importing this package imports no torch; the submodules do. See docs/policies.md.
"""

#: sub-directory of a models root holding one policy per skill: ``ROOT/policy/<skill>/model.*``
POLICY_DIR = "policy"
