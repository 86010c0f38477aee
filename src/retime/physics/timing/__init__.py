"""The timing spline and its optimization: the spline (:mod:`.spline`), Eq. 14 baked per frame
(:mod:`.objective`), the grid optimum it starts from (:mod:`.globalstart`), the optimizers and the
interactive session (:mod:`.optimize`) and the least physical duration (:mod:`.fastest`).
"""
