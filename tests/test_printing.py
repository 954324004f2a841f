"""Readable output: rounding, trig folding, unicode/LaTeX symbols, the model summary."""
import pytest
import sympy as sp

from lsindy_cas import LagrangianSINDy, Library, printing, systems


def test_products_of_trig_fold_into_the_difference_angle():
    text = "1.0*a_dot*b_dot*cos(a)*cos(b) + 1.0*a_dot*b_dot*sin(a)*sin(b)"
    assert printing.plain(text) == "a_dot*b_dot*cos(a - b)"
    a, b = sp.symbols("a b")
    expected = sp.sin(a - b)
    assert sp.simplify(printing.simplify("sin(a)*cos(b) - cos(a)*sin(b)") - expected) == 0


def test_coefficients_equal_only_at_the_precision_shown_also_fold():
    # 0.99999 and 1.00001 agree at 4 significant digits, not at 6
    text = "0.99999*u*cos(a)*cos(b) + 1.00001*u*sin(a)*sin(b)"
    assert printing.plain(text, digits=4) == "u*cos(a - b)"
    six = printing.plain(text, digits=6)          # still exact: the 1e-5 difference stays
    assert six != "u*cos(a - b)"
    a, b, u = sp.symbols("a b u")
    assert sp.expand(sp.expand_trig(sp.sympify(six) - sp.sympify(text))).equals(0)


def test_rounding_to_significant_digits():
    assert printing.plain("0.123456*x + 98765.4*y", digits=3) == "0.123*x + 98800*y"
    assert printing.plain("2.0000000001*x**2", digits=4) == "2*x**2"     # exponents stay integers


def test_pretty_uses_dots_and_subscripts():
    out = printing.pretty("0.5*theta1_dot**2 + Q_theta1*theta1_ddot", coords=["theta1"])
    assert "θ̇₁" in out and "θ̈₁" in out and "Q_θ₁" in out and "theta" not in out


def test_latex_symbols():
    out = printing.latex("theta1_dot*theta2_dot*cos(theta1)*cos(theta2) "
                         "+ theta1_dot*theta2_dot*sin(theta1)*sin(theta2) + Q_x*x_ddot")
    assert out == (r"Q_{x} \ddot{x} + \dot{\theta}_{1} \dot{\theta}_{2} "
                   r"\cos{\left(\theta_{1} - \theta_{2} \right)}")
    assert printing.symbol_latex("theta1", 2) == r"\ddot{\theta}_{1}"
    assert printing.symbol_latex("x") == "x"


def test_a_coordinate_whose_name_ends_in_ddot_is_not_an_acceleration():
    # with the coordinate names given, "a_ddot" is a position, "a_ddot_dot" its velocity
    assert r"\ddot" not in printing.latex("a_ddot_dot**2 + a_ddot", coords=["a_ddot"])
    assert r"\ddot{a}" in printing.latex("a_ddot_dot**2 + a_ddot")      # guessed from the name


@pytest.fixture(scope="module")
def double():
    """The double pendulum's true model, built from its exact coefficients."""
    system = systems.double_pendulum()
    lib = Library.polynomial(system.coords, ["cos(theta1)", "cos(theta2)", "sin(theta1)",
                                              "sin(theta2)", "theta1_dot", "theta2_dot"], 4)
    model = LagrangianSINDy(lib, n_terms=6)
    model._set_coefficients(lib.coefficients(system.hamiltonian))
    return model


def test_describe_the_double_pendulum(double):
    text = printing.describe(double, digits=4, style="plain")
    lines = text.splitlines()
    assert lines[0] == ("H = theta1_dot**2 + theta1_dot*theta2_dot*cos(theta1 - theta2) "
                        "+ 0.5*theta2_dot**2 - 19.62*cos(theta1) - 9.81*cos(theta2)")
    # hand-derived first equation of motion (m1 = m2 = L1 = L2 = 1, g = 9.81)
    t1, t2, d2 = sp.symbols("theta1 theta2 theta2_dot")
    dd1, dd2, Q1 = sp.symbols("theta1_ddot theta2_ddot Q_theta1")
    eq = printing.simplify(double.equations_of_motion()[0])
    expected = (2 * dd1 + dd2 * sp.cos(t1 - t2)) - (Q1 - d2**2 * sp.sin(t1 - t2) - 19.62 * sp.sin(t1))
    got = (eq.lhs - eq.rhs).xreplace({s: sp.Symbol(s.name) for s in eq.free_symbols})
    assert sp.simplify(got - expected) == 0
    assert "cos(theta1 - theta2)" in lines[3]


def test_describe_styles(double):
    pretty = printing.describe(double, style="pretty")
    assert pretty.splitlines()[1].startswith("H = ") and "cos(θ₁ - θ₂)" in pretty
    latex = printing.describe(double, style="latex")
    assert latex.startswith(r"\begin{align*}") and latex.count(r"\\") == 3


def test_bad_arguments():
    with pytest.raises(ValueError, match="digits"):
        printing.plain("x", digits=0)
    with pytest.raises(ValueError, match="style"):
        printing.describe(object(), style="html")
    with pytest.raises(ValueError, match="not fitted"):
        printing.describe(LagrangianSINDy(Library(["x"], ["x**2"]), n_terms=1))
    with pytest.raises(ValueError, match="cannot parse"):
        printing.plain("cos(")
    with pytest.raises(TypeError):
        printing.plain(3.5j)
