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
from .motion import ConstantVelocityModel, CoordinatedTurnModel, MotionModel, cv_matrices, cwna_noise
from .particle import (
    effective_sample_size,
    gaussian_log_likelihood,
    normalize_log_weights,
    propagate,
    resample,
    residual_resample,
    sir_update,
    systematic_resample,
    update_log_weights,
    weighted_cov,
    weighted_mean,
)
from .pcrlb import best_subset, particle_information, pcrlb_step, predicted_information, subset_determinants
from .quantized import (
    level_probabilities,
    mutual_information,
    quantize,
    quantized_fisher_scale,
    quantized_log_likelihood,
    quantized_mutual_information,
)

__all__ = [
    "IMM",
    "ConstantVelocityModel",
    "CoordinatedTurnModel",
    "DegenerateGeometryError",
    "EstimationError",
    "GNResult",
    "IMMModel",
    "InsufficientMeasurementsError",
    "MotionModel",
    "SingularMatrixError",
    "TDOAResult",
    "UpdateResult",
    "best_subset",
    "constant_speed_tof",
    "crb",
    "crb_trace",
    "cv_matrices",
    "cwna_noise",
    "effective_sample_size",
    "ekf_predict",
    "ekf_update",
    "fisher_information",
    "gauss_newton",
    "gauss_newton_batch",
    "gaussian_log_likelihood",
    "kf_predict",
    "kf_update",
    "level_probabilities",
    "measurement_information",
    "multilaterate",
    "mutual_information",
    "normalize_log_weights",
    "particle_information",
    "pcrb_information",
    "pcrb_position",
    "pcrlb_step",
    "predicted_information",
    "propagate",
    "quantize",
    "quantized_fisher_scale",
    "quantized_log_likelihood",
    "quantized_mutual_information",
    "resample",
    "residual_resample",
    "sir_update",
    "subset_determinants",
    "systematic_resample",
    "tdoa_ls",
    "tof_model",
    "update_log_weights",
    "weighted_cov",
    "weighted_mean",
]
