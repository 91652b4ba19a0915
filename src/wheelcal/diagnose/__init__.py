"""The closed loop: find what the model lacks in the residual, add it, report before and after."""
