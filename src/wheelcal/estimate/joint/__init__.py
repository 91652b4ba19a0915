"""The joint maximum-likelihood fit of every parameter at once (:mod:`.fit`) and its parts."""
