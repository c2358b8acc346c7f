"""Data sets: measured benchmarks and synthetic systems with undeclared effects.

``load_cascaded_tanks`` returns the Cascaded Tanks records and ``cascaded_tanks_physics`` the
physical model of its eq. (21); ``load_emps`` and ``load_silverbox`` return the EMPS and
Silverbox records, ``emps_physics`` and ``silverbox_physics`` the textbook models a user would
declare for them and ``emps_reference_physics`` the EMPS benchmark's reference law. The
``make_*`` generators simulate systems whose declared physics misses one effect (the
``hidden_effect`` of the returned Bunch), for checking that a sparse black-box correction finds
what the physics is missing.
"""

from sk_offwhite.datasets._backlash import make_backlash_servo, play
from sk_offwhite.datasets._cascaded_tanks import (
    cascaded_tanks_physics,
    load_cascaded_tanks,
    safe_sqrt,
)
from sk_offwhite.datasets._coupling import make_clearance_coupling
from sk_offwhite.datasets._electrical import make_diode_rc
from sk_offwhite.datasets._emps import emps_physics, emps_reference_physics, load_emps
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
from sk_offwhite.datasets._silverbox import load_silverbox, silverbox_physics
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
    "emps_physics",
    "emps_reference_physics",
    "lagged_command",
    "lagged_reading",
    "load_cascaded_tanks",
    "load_emps",
    "load_silverbox",
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
    "silverbox_physics",
    "stepped_reading",
    "vehicle_dictionary_library",
    "vehicle_physics_known_registers",
]
