"""Policy folders and checkpoints as files: written atomically, loaded as data within limits
(the model zip, the actor rebuilt from its tensors, the normalisation statistics), and the shipped
policies."""
