"""Noise terms of inertial sensors, one module per term behind one interface (:class:`Term`).

Stage ``noise`` of the data flow ``io -> allan -> noise -> inference -> drift -> report -> cli``.
It owns, for every term, its exact sampled-data Allan variance, its phase structure function
(the AVAR-covariance structure), its simulator, its drift contribution and its prior box;
:class:`NoiseModel` sums terms. Adding a term is one module here and its entry in
:data:`~bayes_imu.noise.model.REGISTRY`; the registry checks its declarations
(:func:`~bayes_imu.noise.model.check_declarations`) and ``tests/test_term_contract.py`` runs it
through the contract every term meets. Sensor kinds and drift quantities live in
:mod:`bayes_imu.noise.quantities`.

====================  ===========================================  =============
term                  parameters (units, rate in ``u``)            role
====================  ===========================================  =============
``white``             ``noise_variance`` [u^2]                     short term
``quantization``      ``quantization`` Q [u s]                     short term
``filtered_white``    ``filtered_variance`` [u^2]                  short term
``hf_correlated``     ``correlated_variance`` [u^2], ``..._time_constant`` [s]  short term
``bias_instability``  ``bias_instability`` B [u]                   bias
``gauss_markov``      ``bias_variance`` [u^2], ``time_constant`` [s]  bias
``gauss_markov_2``    ``bias_variance_2`` [u^2], ``time_constant_2`` [s]  bias
``random_walk``       ``rate_random_walk`` K [u/sqrt(s)]           slow
``ramp``              ``rate_ramp`` R [u/s]                        slow
``vibration``         ``vibration_frequency`` [Hz], ``..._amplitude`` [u]  short term
====================  ===========================================  =============
"""

from ._base import (BIAS_STARTS, KALIBR_ROLES, ORDERS, ROLES, SELECTION_ROLES, TAIL_KINDS,
                    CovarianceTail, PriorScale, Term, calibrated_contrast, check_order)
from .model import PARAMETER_UNITS, REGISTRY, TERM_PARAMETERS, TERMS, NoiseModel, check_declarations

__all__ = ["Term", "PriorScale", "CovarianceTail", "NoiseModel", "REGISTRY", "TERMS",
           "TERM_PARAMETERS", "PARAMETER_UNITS", "BIAS_STARTS", "ROLES", "ORDERS", "TAIL_KINDS",
           "SELECTION_ROLES", "KALIBR_ROLES", "calibrated_contrast", "check_order",
           "check_declarations"]
