"""Pure estimation maths (numpy/scipy only, no SimPy, no kernel): Kalman / extended Kalman
filters, IMM, CV and coordinated-turn motion models, Gauss-Newton ToF localization with a
Levenberg-Marquardt fallback, linearized TDOA and multilateration, CRB / PCRB, and a
vectorized particle-filter core."""

from .bounds import (
    crb,
    crb_trace,
    fisher_information,
    measurement_information,
    pcrb_information,
    pcrb_position,
)
from .errors import (
    DegenerateGeometryError,
    EstimationError,
    InsufficientMeasurementsError,
    SingularMatrixError,
)
from .gauss_newton import GNResult, constant_speed_tof, gauss_newton, gauss_newton_batch, tof_model
from .imm import IMM, IMMModel
from .kalman import UpdateResult, ekf_predict, ekf_update, kf_predict, kf_update
from .lsq import TDOAResult, multilaterate, tdoa_ls
from .motion import ConstantVelocity, CoordinatedTurn, MotionModel, cv_matrices, cwna_noise
from .particle import (
    effective_sample_size,
    gaussian_log_likelihood,
    normalize_log_weights,
    propagate,
    resample,
    residual_resample,
    systematic_resample,
    update_log_weights,
    weighted_cov,
    weighted_mean,
)

__all__ = [
    "EstimationError", "DegenerateGeometryError", "InsufficientMeasurementsError", "SingularMatrixError",
    "UpdateResult", "kf_predict", "kf_update", "ekf_predict", "ekf_update",
    "MotionModel", "ConstantVelocity", "CoordinatedTurn", "cv_matrices", "cwna_noise",
    "IMM", "IMMModel",
    "GNResult", "gauss_newton", "gauss_newton_batch", "tof_model", "constant_speed_tof",
    "TDOAResult", "multilaterate", "tdoa_ls",
    "fisher_information", "crb", "crb_trace", "measurement_information", "pcrb_information", "pcrb_position",
    "propagate", "gaussian_log_likelihood", "normalize_log_weights", "update_log_weights",
    "effective_sample_size", "systematic_resample", "residual_resample", "resample",
    "weighted_mean", "weighted_cov",
]
