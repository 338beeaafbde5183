"""Models the estimators are built from (pure maths)."""
