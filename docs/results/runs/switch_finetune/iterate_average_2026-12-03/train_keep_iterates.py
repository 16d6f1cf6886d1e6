"""python train_keep_iterates.py <hydra overrides>: agrl.train, also saving every iterate's actor and critic."""
import copy, sys
from pathlib import Path
import torch
import agrl.rl.trainer as trainer_module
from agrl import train

iterates = []
original_learn = trainer_module.Trainer.learn
original_final = trainer_module.Trainer.final_evaluation

def learn(self, data):
    out = original_learn(self, data)
    iterates.append({"actor": copy.deepcopy(self.actor.state_dict()), "critic": copy.deepcopy(self.critic.state_dict())})
    return out

def final_evaluation(self):
    torch.save(iterates, Path(self.run_dir) / "iterates.pt")
    return original_final(self)

trainer_module.Trainer.learn = learn
trainer_module.Trainer.final_evaluation = final_evaluation
train.main()
