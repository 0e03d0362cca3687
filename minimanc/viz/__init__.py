"""Every figure and animation of the chapters, apart from the math that they show.

The one door for figures: ``minimanc.viz.X`` for each kind of figure, and no other module
draws.  None of them imports matplotlib (or Pillow) until a figure is drawn, and no math,
model or world module imports this package, so importing those never loads a plotting
library:

* :mod:`minimanc.viz.style` — names and colours of the models and metrics, ``save``, and the
  pieces every figure shares (all chapters);
* :mod:`minimanc.viz.exercises` — chapter 0: each exercises notebook's last figure, drawn
  from the student's own functions over the library's (chapters 1, 2, 3);
* :mod:`minimanc.viz.graph` — chapter 1: a computation graph with the cotangent on each
  edge;
* :mod:`minimanc.viz.automaton` — chapter 5: the vAGN automaton graph and the
  q-distribution heat map;
* :mod:`minimanc.viz.saliency` — chapter 6: the paper's colormap, CAM/saliency overlays and
  the per-q-state saliency panel;
* :mod:`minimanc.viz.world` — chapter 7: map plots, raster galleries with routes, scene
  animations;
* :mod:`minimanc.viz.study` — chapter 9: the study's figures (Table I, families, sample
  efficiency, model sizes, q-states, ablation);
* :mod:`minimanc.viz.explain` — chapter 9: one closed-loop rollout (paths, speeds, q against
  the human's modes, the Fig. 4 trace, Fig. 3 saliency, the GIF);
* :mod:`minimanc.viz.highway` — chapter 10: a highway-env episode (path and speed) driven by
  the student's controller over the library's;
* :mod:`minimanc.viz.dagger` — chapter 11: a metric over DAgger's rounds against behaviour
  cloning at the same budget;
* :mod:`minimanc.viz.investigation` — chapter 12: faded-history boxes and the privileged
  learner's input ablation.
"""

from minimanc.viz import (
    automaton,
    dagger,
    exercises,
    explain,
    graph,
    highway,
    investigation,
    saliency,
    study,
    style,
    world,
)

__all__ = ["automaton", "dagger", "exercises", "explain", "graph", "highway", "investigation",
           "saliency", "study", "style", "world"]
