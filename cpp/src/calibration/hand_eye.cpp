// placeholder: hand-eye calibration (being written)
#include "scanalign/calibration/hand_eye.hpp"
