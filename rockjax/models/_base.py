r"""The interface every rocking model gives the integrators.

A rocking model is a hybrid system: a smooth flow per discrete *mode* (which side of
$u = 0$, before or after lift-off, which corner is the pivot, ...), *events* that end a
mode, and *jump maps* applied at events (impacts, lift-off and landing, pivot changes,
coming to rest). The integrators of `rockjax.integrators` consume only this interface,
one member at a time (the batched stepper `jax.vmap`s it), so a model written once runs
on every integrator, and a fix to a jump rule lands once.

A model never imports an integrator.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp


class Flags(eqx.Module):
    """What a jump did, for the integrator's bookkeeping (boolean scalars).

    - `impact`: it counts as a rocking impact (Eqs 2–3; recorded in `impact_times`).
    - `overturned`: the structure overturned; the run stops with status `overturned`.
    - `rest`: the body has come to rest for good (free vibration out of energy); the
      run stops with status `completed`.
    """

    impact: jnp.ndarray
    overturned: jnp.ndarray
    rest: jnp.ndarray


class Observed(eqx.Module):
    """What a model reports of its state, in the units of `rockjax.Response`.

    `u` [m] horizontal displacement of the top mass, `v` [m/s] its rate, `theta` [rad]
    rotation of the body, `uplift` [m] of the lifted corner.
    """

    u: jnp.ndarray
    v: jnp.ndarray
    theta: jnp.ndarray
    uplift: jnp.ndarray


class AbstractRockingModel(eqx.Module):
    """A rocking model: state and mode, flow, events, jump maps and observables.

    Every method works on ONE member: the state `y` is a 1-D array (for the SDOF models
    `[u, v]`, for the 2-DOF body the corner heights and their rates), the mode a pytree of
    scalars. `a_g` [m/s²] is the ground acceleration at that instant.

    Abstract: a model is a final subclass that implements every abstract method and
    declares the class data below (equinox's abstract/final pattern).
    """

    @abc.abstractmethod
    def init(self, structure, u0, v0, first, forced: bool):
        """`(y, mode)` for a release from top displacement `u0` [m] and rate `v0` [m/s].

        `first` is the direction (+1 or -1) of the first motion a ground motion would
        cause from rest; `forced` (static) says whether a ground motion acts.
        """

    @abc.abstractmethod
    def start(self, structure, y, mode, a_g):
        """`(y, mode)` at the start of a run, under the ground acceleration `a_g` [m/s²]
        at t = 0: for a state whose conditions already lie past their surface there
        (events fire when a condition reaches zero, not when it starts below it)."""

    @abc.abstractmethod
    def vector_field(self, structure, y, mode, a_g):
        """$dy/dt$ in the given mode under ground acceleration `a_g` [m/s²]."""

    @abc.abstractmethod
    def conditions(self, structure, y, mode, a_g):
        """Event conditions, a 1-D array: each is > 0 inside the mode, and an event
        fires when one falls to 0. Inactive conditions hold a positive constant."""

    @abc.abstractmethod
    def jump(self, structure, y, mode, which, r, a_g):
        """`(y, mode, Flags)` after event `which` (an int index into `conditions`).

        The state is projected onto the event's surface exactly (e.g. u = 0 at an
        impact). `r` is the coefficient of restitution (Eq. 2).
        """

    @abc.abstractmethod
    def observe(self, structure, y, mode) -> Observed:
        """u, v, theta, uplift of a state (see `Observed`)."""

    @abc.abstractmethod
    def frequency(self, structure):
        """The highest natural frequency [rad/s] of the flow (fixed-step stability)."""

    @abc.abstractmethod
    def u_overturn(self, structure):
        """|u| [m] at which the body overturns."""

    @abc.abstractmethod
    def tracked_uplift(self, structure, y, mode):
        """The uplift [m] the integrators track for the peak (the observed uplift, or 0
        where the peak uplift follows from the peak |u|: `peak_uplift`)."""

    @abc.abstractmethod
    def peak_uplift(self, structure, peak_u, tracked):
        """The run's peak uplift [m] from its peak |u| [m] and the largest uplift the
        integrator saw at its step ends (`tracked`)."""

    @abc.abstractmethod
    def peak_coordinate(self, structure, y, mode):
        """`(q, dq/dt)`: the coordinate whose peak |q| the batched stepper tracks over a
        step (the maximum of its cubic Hermite interpolant), and its rate; |u| is an
        increasing function of |q| (`u_of_peak`). u [m] and v [m/s] of `observe` for the
        SDOF models; a model whose u is costly to observe tracks a state variable
        (`RigidBody`: theta, where u would take a sine and a cosine at both ends of every
        step)."""

    @abc.abstractmethod
    def peak_limit(self, structure):
        """|q| of `peak_coordinate` at overturning (`u_overturn` [m] where q is u)."""

    @abc.abstractmethod
    def u_of_peak(self, structure, q):
        """The peak |u| [m] of a peak |q| of `peak_coordinate` (q itself where q is u)."""

    @abc.abstractmethod
    def theta_uplift_of_u(self, structure, u):
        """(theta [rad], uplift [m]) as functions of u [m], for output times between grid
        points; only where `kinematics_of_u` (else it raises `NotImplementedError`)."""

    #: whether theta and uplift are functions of u alone (`theta_uplift_of_u`)
    kinematics_of_u: eqx.AbstractClassVar[bool]
    #: whether a condition that starts on its surface right after a jump and leaves it may
    #: cross it again later in the same step as a different event: True for `RigidBody`,
    #: whose landing condition crosses zero again at the lift-off on the other corner; the
    #: SDOF models keep False: their condition's return is the next impact at u = 0 of a
    #: settling rigid block, collapsed onto the jump when it comes within one step. The
    #: stepper's default for its `grazing_roots` setting.
    recrossing_conditions: eqx.AbstractClassVar[bool]
    #: whether `peak_coordinate` reads components of the state (free: the SDOF models'
    #: u and v, the rigid body's theta): the batched stepper then evaluates a step's
    #: interior turn only where it could raise a member's peak (for a coordinate computed
    #: from the state, as the 2-DOF body's u, evaluating it twice would cost more)
    peak_from_state: eqx.AbstractClassVar[bool]
    #: contacts whose events are independent of each other (the 2-DOF body's two corners:
    #: 2; the SDOF and the rigid body: 1), for the events a step may hold
    contacts: eqx.AbstractClassVar[int]

    @property
    @abc.abstractmethod
    def impacts_accumulate(self) -> bool:
        """Whether the impacts of a settling body accumulate (Housner's rigid block:
        infinitely many in a finite time), crowding a step with events."""
