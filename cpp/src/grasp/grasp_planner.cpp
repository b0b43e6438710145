// placeholder: grasp planning (being written)
#include "scanalign/grasp/grasp_planner.hpp"
