"""`poles finetune`: a team's own export to a deployable model, with what it gained and what it lost."""
