"""The teaching floor: sympy derivations, the literal F_x reference (the test oracle) and the
notebooks' helpers. Imports core and the leaves."""
