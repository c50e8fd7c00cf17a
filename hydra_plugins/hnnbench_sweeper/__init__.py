"""hnnbench's Hydra sweeper, where Hydra looks for plugins (the ``hydra_plugins``
namespace). The implementation is :class:`hnnbench._sweeping.sweeper.Sweeper`; conf/config.yaml
selects it (``hydra/sweeper=hnnbench``)."""

from hnnbench._sweeping.sweeper import Sweeper


class HnnbenchSweeper(Sweeper):
    """Hydra's basic sweeper without its per-job validation composition, collecting the
    jobs' outcomes (:class:`hnnbench._sweeping.sweeper.Sweeper`)."""


__all__ = ["HnnbenchSweeper"]
