within UWCoSim.Functions;
function normalCdf
  "Standard normal distribution function Phi(u) (Abramowitz-Stegun 26.2.17, |error| < 7.5e-8)"
  input Real u "Argument";
  output Real p "Phi(u)";
protected
  constant Real pi = 3.14159265358979323846;
  Real t;
  Real q;
algorithm
  t := 1/(1 + 0.2316419*abs(u));
  q := exp(-u*u/2)/sqrt(2*pi)*t*(0.319381530 + t*(-0.356563782 + t*(1.781477937
    + t*(-1.821255978 + t*1.330274429))));
  p := if u >= 0 then 1 - q else q;
end normalCdf;
