// doctest entry point of preisach_cpp_tests; the test cases live in the other *.cpp files.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>
