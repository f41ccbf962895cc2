"""``python -m nbv.preview preview=out.png [seed=S] [per_category=K] [tile=T]`` (or ``make
preview``): draw the contact sheet of the synthetic shapes.

Settings: ``conf/preview.yaml`` (declared by :class:`nbv.preview.config.PreviewSettings`). A
refused setting ends with one line on stderr and exit status 2 (:mod:`nbv.config.cli`).
"""

import logging
import time

from nbv.config.cli import command
from nbv.preview.config import ENTRY, PreviewSettings

PROG = "nbv.preview"
# Named, not __name__ (which is "__main__" under `python -m`), so the job log says who speaks.
log = logging.getLogger("nbv.preview")


def finish(s: PreviewSettings) -> None:
    from nbv.assets.synthetic.preview import preview

    begin = time.perf_counter()
    preview(s.preview, seed=s.seed, per_category=s.per_category, tile=s.tile)
    log.info("wrote %s in %.1f s", s.preview, time.perf_counter() - begin)


main = command(PROG, "preview", ENTRY.build, finish)

if __name__ == "__main__":
    main()
