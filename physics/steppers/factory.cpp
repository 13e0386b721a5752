#include "physics/steppers/stepper.h"

#include <stdexcept>

namespace substep {

std::unique_ptr<Stepper> makeDirectStepper();
std::unique_ptr<Stepper> makePgsStepper();

std::unique_ptr<Stepper> makeStepper(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return makeDirectStepper();
    case Algorithm::A2: return makePgsStepper();
    default: break;
  }
  throw std::invalid_argument(std::string("algorithm ") + algorithmName(a) + " is not implemented yet");
}

}  // namespace substep
