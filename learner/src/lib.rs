//! Learner: PPO (issue 4). Empty for now.
