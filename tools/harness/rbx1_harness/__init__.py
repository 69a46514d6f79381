"""rbx1_harness - the RBX1 link protocol conformance suite (tools/rbx1-harness): runner, board helpers, checks."""
