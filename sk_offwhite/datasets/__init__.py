"""Data sets: the measured Cascaded Tanks benchmark and synthetic systems with undeclared effects.

``load_cascaded_tanks`` returns the benchmark records and ``cascaded_tanks_physics`` the
physical model of its eq. (21). The ``make_*`` generators simulate systems whose declared
physics misses one effect (the ``hidden_effect`` of the returned Bunch), for checking that a
sparse black-box correction finds what the physics is missing.
"""

from sk_offwhite.datasets._backlash import make_backlash_servo, play
from sk_offwhite.datasets._cascaded_tanks import (
    cascaded_tanks_physics,
    load_cascaded_tanks,
    safe_sqrt,
)
from sk_offwhite.datasets._coupling import make_clearance_coupling
from sk_offwhite.datasets._electrical import make_diode_rc
from sk_offwhite.datasets._lag import (
    lagged_command,
    make_delayed_drive,
    make_delayed_heater,
    make_lagged_drive,
    make_lagged_heater,
)
from sk_offwhite.datasets._mechanical import (
    make_coulomb_drive,
    make_dead_zone_motor,
    make_duffing_oscillator,
    make_pendulum_drag,
)
from sk_offwhite.datasets._sensor import (
    lagged_reading,
    make_nonlinear_sensor_tank,
    make_slow_sensor_tank,
    make_stepped_sensor_tank,
    sensor_reading,
    stepped_reading,
)
from sk_offwhite.datasets._synthetic import (
    make_cascaded_tanks,
    make_friction_oscillator,
    make_leaky_tank,
    make_saturating_actuator,
    make_vehicle_lateral,
    vehicle_dictionary_library,
)
from sk_offwhite.datasets._thermal import make_convective_block, make_heated_block
from sk_offwhite.datasets._vehicle import vehicle_physics_known_registers
from sk_offwhite.effects._lags import delayed_command

__all__ = [
    "cascaded_tanks_physics",
    "delayed_command",
    "lagged_command",
    "lagged_reading",
    "load_cascaded_tanks",
    "make_backlash_servo",
    "make_cascaded_tanks",
    "make_clearance_coupling",
    "make_convective_block",
    "make_coulomb_drive",
    "make_dead_zone_motor",
    "make_diode_rc",
    "make_duffing_oscillator",
    "make_friction_oscillator",
    "make_heated_block",
    "make_delayed_drive",
    "make_delayed_heater",
    "make_lagged_drive",
    "make_lagged_heater",
    "make_leaky_tank",
    "make_nonlinear_sensor_tank",
    "make_pendulum_drag",
    "make_saturating_actuator",
    "make_slow_sensor_tank",
    "make_stepped_sensor_tank",
    "make_vehicle_lateral",
    "play",
    "safe_sqrt",
    "sensor_reading",
    "stepped_reading",
    "vehicle_dictionary_library",
    "vehicle_physics_known_registers",
]
