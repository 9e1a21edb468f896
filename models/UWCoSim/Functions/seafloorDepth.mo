within UWCoSim.Functions;
function seafloorDepth
  "Analytic stand-in for the bathymetry map h_d(x, y) (depth, positive down)"
  input Real x(unit = "m") "East position";
  input Real y(unit = "m") "North position";
  input Real meanDepth(unit = "m") = 1000 "Mean depth";
  input Real slope = 0.01 "Regional slope (m/m), along +x";
  input Real amplitude(unit = "m") = 60 "Relief amplitude";
  input Real wavelength(unit = "m") = 5000 "Relief wavelength";
  input Real xc(unit = "m") = 12500 "Centre of the map (east)";
  input Real yc(unit = "m") = 12500 "Centre of the map (north)";
  output Real h(unit = "m") "Depth of the seafloor at (x, y)";
protected
  constant Real pi = 3.14159265358979323846;
algorithm
  h := meanDepth + slope*(x - xc)
    + amplitude*sin(2*pi*x/wavelength)*cos(2*pi*y/wavelength);
  annotation (Documentation(info = "<html>
<p>Smooth analytic seafloor used in place of the project's bathymetry map. In the Python
package and the DepthSounder FMU, <code>h_d</code> is the C2 cubic B-spline interpolating a
gridded map (synthetic or GEBCO), read from an external coefficient file
(<code>uwcosim.models.bathymetry</code>); in Modelica that map would be an external table
(e.g. <code>Modelica.Blocks.Tables.CombiTable2Ds</code> or an <code>ExternalObject</code>),
which this package does not depend on. This stand-in keeps the model self-contained:</p>
<pre>h = meanDepth + slope*(x - xc) + amplitude*sin(2 pi x/wavelength)*cos(2 pi y/wavelength)</pre>
</html>"));
end seafloorDepth;
