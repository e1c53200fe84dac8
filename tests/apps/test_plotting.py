"""The tendon plot's time axis is in seconds: 150 control steps at 30 Hz span 5 s."""

import numpy as np

from jgrounding import sim
from jgrounding.apps import plotting


def test_tendon_plot_time_axis_is_in_seconds():
    fig, ax = plotting.plt.subplots()
    plotting.plot_tendons(ax, np.zeros((sim.NUM_STEPS, 4)))
    x = ax.lines[0].get_xdata()
    assert ax.get_xlabel() == "time (s)"
    assert x[0] == 0.0 and np.isclose(x[-1], (sim.NUM_STEPS - 1) * sim.CONTROL_DT)
    assert np.isclose(x[-1] + sim.CONTROL_DT, 5.0)
    plotting.plot_tendons(ax, np.zeros((10, 4)), dt=0.5)
    assert np.isclose(ax.lines[-1].get_xdata()[-1], 4.5)
    plotting.plt.close(fig)
