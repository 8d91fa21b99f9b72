//! Actor: environment, planners, rollouts (issue 3). Empty for now.
