// Placeholder: real tests follow.
#include <doctest/doctest.h>
