r"""Sensors that do not read what the physics predicts: an offset, a curve, a step."""

from __future__ import annotations

import jax
import numpy as np

from .._physics import Parameter
from ._base import OutputEffect, _checked_corner, _corner_parameters, _hinge_corner

__all__ = ["OutputOffset", "SensorCalibration", "SensorStep"]


class OutputOffset(OutputEffect):
    r"""The measured output reads the model output plus a constant: $z \leftarrow z + b$.

    An uncalibrated sensor whose zero is not the physical zero of the state it measures;
    the dynamics then act on the physical level $z - b$. Parameter ``{name}_offset``
    ($b$).
    """

    def __init__(self, output: int, *, offset: float = 0.0, name: str = "sensor"):
        self.output, self.offset, self.name = int(output), float(offset), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_offset": Parameter(self.offset)}

    def apply_output(self, x, u, z, theta):
        return z.at[self.output].add(theta[f"{self.name}_offset"])

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the sensor of {output_names[self.output]} reads with a constant offset"


class SensorCalibration(OutputEffect):
    r"""Output ``output`` reads a static polynomial of what the physics predicts.

    An uncalibrated sensor whose reading is not linear in the quantity it measures (a
    level sensor, a thermocouple, a strain gauge):

    $$
    z \leftarrow z + \sum_{k=0}^{d} c_k\,\xi^k, \qquad
    \xi = \frac{z - m}{s},
    $$

    with parameters ``{name}_c0`` ... ``{name}_c{d}`` ($c_k$, in the output's units,
    starting at 0: the declared output map). The centre $m$ and scale $s$
    are fixed numbers taken from the data (the loop uses the mean and standard deviation
    of the simulated output), so $\xi$ is dimensionless and the fitted curve does
    not depend on the units of the data. With $d = 0$ this is
    [`OutputOffset`][sk_offwhite.OutputOffset]; $c_1$ is a gain error, $c_2$ a curvature.
    """

    def __init__(
        self, output: int, center: float, scale: float, *, degree: int = 2, name: str = "sensor"
    ):
        if not (np.isfinite(center) and np.isfinite(scale) and scale > 0):
            raise ValueError(f"center and scale must be finite, scale > 0; got {center}, {scale}.")
        if isinstance(degree, bool) or int(degree) != degree or degree < 0:
            raise ValueError(f"degree must be an integer >= 0, got {degree!r}.")
        self.output, self.center, self.scale = int(output), float(center), float(scale)
        self.degree, self.name = int(degree), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_c{k}": Parameter(0.0) for k in range(self.degree + 1)}

    def apply_output(self, x, u, z, theta):
        xi = (z[self.output] - self.center) / self.scale
        reading = theta[f"{self.name}_c{self.degree}"]
        for k in range(self.degree - 1, -1, -1):
            reading = reading * xi + theta[f"{self.name}_c{k}"]
        return z.at[self.output].add(reading)

    def describe(self, state_names, output_names, values=None) -> str:
        return (
            f"the sensor of {output_names[self.output]} reads a degree-{self.degree} "
            "polynomial of it (an uncalibrated, nonlinear sensor)"
        )


class SensorStep(OutputEffect):
    r"""The reading of output ``output`` steps by a height where it passes a level.

    A sensor whose reading is discontinuous (a seam in a capacitive level strip, a worn
    spot on a potentiometer) jumps each time the quantity passes one value:

    $$
    z \leftarrow z + H\,\sigma\!\left(\frac{z - L}{c}\right),
    $$

    with $\sigma$ the logistic function and parameters ``{name}_level``
    ($L$) and ``{name}_height`` ($H$, positive when the reading steps up as
    the level rises), both in the output's units: below the level the reading is what
    the rest of the model says, above it $H$ more (an offset of the whole reading
    is another effect, [`OutputOffset`][sk_offwhite.OutputOffset]). The step is rounded over
    ``corner`` ($c$, output units; fitted as ``{name}_corner`` with ``fit_corner=True``, see
    [`Overflow`][sk_offwhite.Overflow]); the loop sets it to 2.5 % of the simulated output's
    standard deviation, starts $L$ and $H$ from the measured jumps
    ([`output_jumps`][sk_offwhite.diagnose.output_jumps]) and keeps $L$ within
    ``level_bounds``, the measured values the reading jumped across: the data place the
    step, and a fit may not move it to where it would stand for some other misfit of the
    model. It acts on the final reading, after
    every other output effect (`Effect.reads_output`), so that
    $L$ is a measured value.
    """

    reads_output = True

    def __init__(
        self,
        output: int,
        level: float,
        height: float = 0.0,
        *,
        level_bounds=(None, None),
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "step",
    ):
        self.output, self.level, self.height = int(output), float(level), float(height)
        self.level_bounds = tuple(level_bounds)
        self.corner, self.fit_corner = _checked_corner(corner), bool(fit_corner)
        self.name = name

    def parameters(self) -> dict[str, Parameter]:
        return {
            f"{self.name}_level": Parameter(self.level, self.level_bounds),
            f"{self.name}_height": Parameter(self.height),
            **_corner_parameters(self),
        }

    def apply_output(self, x, u, z, theta):
        reading = z[self.output]
        above = jax.nn.sigmoid((reading - theta[f"{self.name}_level"]) / _hinge_corner(self, theta))
        return z.at[self.output].add(theta[f"{self.name}_height"] * above)

    def describe(self, state_names, output_names, values=None) -> str:
        values = values or {}
        level = values.get(f"{self.name}_level", self.level)
        height = values.get(f"{self.name}_height", self.height)
        return (
            f"the reading of {output_names[self.output]} steps by {height:.3g} where it "
            f"passes {level:.4g} (a discontinuous sensor)"
        )
