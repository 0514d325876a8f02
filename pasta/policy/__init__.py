"""Per-skill point-cloud policies at run time (torch): PointNet++ over dough + tool + sub-goal points.

- :mod:`pasta.policy.pointnet2`: farthest point sampling, ball query, set abstraction, PointNet++;
- :mod:`pasta.policy.network`: :class:`~pasta.policy.network.PolicyNet` (action in [-1, 1] + done logit);
- :mod:`pasta.policy.learned`: :class:`~pasta.policy.learned.LearnedPolicy`, attached to a skill with
  ``skill.attach_policy``; its ``controller(skill)`` drives the skill in the simulator;
- :mod:`pasta.policy.reset`: the learned reset (start) pose of a skill's tool, loaded beside the policy.

Their trainers live in :mod:`pasta.train` (behaviour cloning :mod:`pasta.train.policy`, the reset pose
:mod:`pasta.train.reset`, the stopping rule :mod:`pasta.train.select`, single-skill evaluation
:mod:`pasta.train.evaluate`); nothing here imports them. Importing this package imports no torch; the
submodules do. See docs/policies.md.
"""

#: sub-directory of a models root holding one policy per skill: ``ROOT/policy/<skill>/model.*``
POLICY_DIR = "policy"
